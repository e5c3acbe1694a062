"""Config fields at the ends of their valid ranges: the firmware must run or refuse with one error line
naming the field, never crash.

common/config/schema.toml gives each field's range; a value the schema accepts is one a user may
flash, so the matcher, the detector and the robot loop must survive it.

- Matcher sections and ``[detect]``, field by field: each numeric field alone at its ``min`` and at its
  ``max`` (booleans at both values) in a one-line config over the defaults; ``fuzzystereo match`` on a
  160 x 139 Aloe pair (opencv-doc), ``fuzzystereo detect`` on a generated frame.
- Robot-loop sections, section by section: every numeric field of the section at its ``min`` at once,
  then at its ``max``; and the whole config (every section) at its ``min`` and at its ``max``;
  ``fuzzystereo run --source sim:... --max-frames 6``. (Field by field, the ~320 loop cases took 3 min on
  the 2-core build machine: measured once in session 51, all passed, not repeated in every run.)

A run passes when it exits 0, or exits 2 with a config error that names the field (a cross-field rule,
e.g. ``road_slope_min`` above the default ``road_slope_max``); anything else — a signal, an abort, a
timeout, another exit code — fails, listed with its command. In session 51 the same cases also passed
under the ASan + UBSan build (``FUZZYSTEREO_BIN=build/asan/fuzzystereo``).
"""

from __future__ import annotations

import os
import subprocess
import tomllib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

pytestmark = [pytest.mark.firmware, pytest.mark.slow]

MATCHER_SECTIONS = ("segmentation", "cost", "esr", "densify", "boundary", "fis", "lr_check", "runtime")
LOOP_SECTIONS = ("tracker", "planner", "loop", "robot", "watchdog", "motors", "camera", "perception", "record")
ALOE = Path("/usr/share/doc/opencv-doc/examples/data")


def limit_value(spec: dict, lim: str) -> object:
    """A numeric field's schema limit (lim: "min" or "max"), moved inwards to the nearest odd integer for
    fields that must be odd."""
    v = spec[lim]
    if spec["type"] == "int" and spec.get("odd") and v % 2 == 0:
        v = v + 1 if lim == "min" else v - 1
    return v


def toml_value(v: object) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else repr(v)


def field_cases(schema: dict, sections: tuple[str, ...]) -> list[tuple[str, str, str]]:
    """One case (name, config text, the field an error must name) per numeric field's min and max and
    per value of every bool of the sections, each field alone."""
    cases = []
    for section in sections:
        for key, spec in schema[section].items():
            kind = spec.get("type")
            values = ([True, False] if kind == "bool" else
                      [limit_value(spec, lim) for lim in ("min", "max") if lim in spec] if kind in ("int", "float")
                      else [])
            for v in values:
                cases.append((f"{section}.{key} = {toml_value(v)}", f"[{section}]\n{key} = {toml_value(v)}\n",
                              f"{section}.{key}"))
    assert cases, f"no fields in {sections}"
    return cases


def limit_case(schema: dict, sections: tuple[str, ...], lim: str) -> tuple[str, str, None]:
    """One case with every numeric field of the sections at its limit at once (no single field to name)."""
    lines = []
    for section in sections:
        lines.append(f"[{section}]")
        lines += [f"{key} = {toml_value(limit_value(spec, lim))}" for key, spec in schema[section].items()
                  if spec.get("type") in ("int", "float") and lim in spec]
    name = f"every field of [{sections[0]}] at its {lim}" if len(sections) == 1 else f"the whole config at its {lim}"
    return name, "\n".join(lines) + "\n", None


def run_ok(cmd: list, name: str, section_key: str | None = None) -> str | None:
    """None when the command exits 0 (or 2 with a config error naming section_key), else the failure."""
    try:
        p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=180,
                           env={**os.environ, "OMP_NUM_THREADS": "1"})
    except subprocess.TimeoutExpired:
        return f"{name}: timed out after 180 s ({' '.join(map(str, cmd))})"
    last = (p.stderr.strip().splitlines() or [""])[-1]
    if p.returncode == 0:
        return None
    if section_key and p.returncode == 2 and "config error" in last and section_key in last:
        return None
    return f"{name}: exit {p.returncode}, last line {last!r} ({' '.join(map(str, cmd))})"


def run_cases(tmp: Path, cases: list, command) -> list[str]:
    """command(config_path, out_dir) for every (name, config text, field) case, 2 at a time; the failures."""

    def one(i_case):
        i, (name, text, section_key) = i_case
        cfg = tmp / f"c{i}.toml"
        cfg.write_text(text)
        return run_ok(command(cfg, tmp / f"o{i}"), name, section_key)

    with ThreadPoolExecutor(max_workers=2) as pool:
        return [r for r in pool.map(one, enumerate(cases)) if r]


@pytest.fixture(scope="module")
def schema(common_dir) -> dict:
    return tomllib.loads((common_dir / "config" / "schema.toml").read_text())


def test_matcher_fields_at_their_range_ends(firmware_bin, schema, tmp_path):
    if not (ALOE / "aloeL.jpg").is_file():
        pytest.skip(f"{ALOE}/aloeL.jpg not found (Debian package opencv-doc)")
    import cv2

    left, right = tmp_path / "l.png", tmp_path / "r.png"
    for src, dst in ((ALOE / "aloeL.jpg", left), (ALOE / "aloeR.jpg", right)):
        cv2.imwrite(str(dst), cv2.resize(cv2.imread(str(src)), (160, 139), interpolation=cv2.INTER_AREA))
    failures = run_cases(tmp_path, field_cases(schema, MATCHER_SECTIONS),
                         lambda cfg, out: [firmware_bin, "match", "--left", left, "--right", right, "--config", cfg,
                                           "--out", out])
    assert not failures, "\n".join(failures)


def test_detector_fields_at_their_range_ends(firmware_bin, schema, tmp_path):
    gen = tmp_path / "syn"
    subprocess.run([str(firmware_bin), "sim", "generate", "--count", "1", "--seed", "5", "--out", str(gen)],
                   check=True, capture_output=True)
    d = gen / "training"
    failures = run_cases(tmp_path, field_cases(schema, ("detect",)),
                         lambda cfg, out: [firmware_bin, "detect", "--left", d / "image_2" / "000000_10.png",
                                           "--right", d / "image_3" / "000000_10.png", "--calib",
                                           d / "sim_gt" / "000000_10.json", "--config", cfg, "--out", out])
    assert not failures, "\n".join(failures)


def test_robot_loop_sections_at_their_range_ends(firmware_bin, schema, common_dir, tmp_path):
    scene = common_dir / "sim" / "scenes" / "demo.toml"
    cases = [limit_case(schema, (s,), lim) for s in LOOP_SECTIONS if s in schema for lim in ("min", "max")]
    cases += [limit_case(schema, tuple(schema), lim) for lim in ("min", "max")]  # the whole config at once
    failures = run_cases(tmp_path, cases, lambda cfg, out: [firmware_bin, "run", "--source", f"sim:{scene}", "--motors",
                                                            "sim", "--config", cfg, "--max-frames", "6", "--quiet"])
    assert not failures, "\n".join(failures)
