"""[detect] input ("esr" | "dense"): the map detection reads, in `detect` and `detect-eval` (fresh
and through --disparity-cache, which holds the ESR map and is densified after reading). Tiny
generated frames (tests/python/detect_synth.py)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

import detect_synth

pytestmark = pytest.mark.firmware


def run(binary: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return detect_synth.write_dataset(tmp_path_factory.mktemp("sim"))


def config(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / f"{name}.toml"
    p.write_text(text)
    return p


def detect(binary: Path, dataset: Path, cfg: Path, out: Path) -> tuple[np.ndarray, list]:
    tr, stem = dataset / "training", "000000_10"
    p = run(binary, "detect", "--left", tr / "image_2" / f"{stem}.png", "--right", tr / "image_3" / f"{stem}.png",
            "--calib", tr / "sim_gt" / f"{stem}.json", "--max-disparity", "32", "--config", cfg, "--out", out)
    assert p.returncode == 0, p.stderr
    disp = cv2.imread(str(out / "disp_left.png"), cv2.IMREAD_UNCHANGED)  # the map the detector read, 0 = none
    boxes = [[*o["box"], round(o["distance_m"], 6)] for o in json.loads((out / "obstacles.json").read_text())["obstacles"]]
    return disp, boxes


def test_detect_reads_the_chosen_map(firmware_bin, dataset, tmp_path):
    esr, _ = detect(firmware_bin, dataset, config(tmp_path, "e", '[detect]\ninput = "esr"\n'), tmp_path / "e")
    dense, _ = detect(firmware_bin, dataset, config(tmp_path, "d", '[detect]\ninput = "dense"\n'), tmp_path / "d")
    off, _ = detect(firmware_bin, dataset,
                    config(tmp_path, "o", '[detect]\ninput = "dense"\n[densify]\nenabled = false\n'), tmp_path / "o")
    holes = lambda d: int((d == 0).sum())  # noqa: E731
    assert holes(esr) > 0.05 * esr.size  # the sparse map has holes (LR check, ESR)
    assert holes(dense) == 0  # the 8-direction fill leaves none
    np.testing.assert_array_equal(off, esr)  # dense without the densify stage is the ESR map
    # Where the ESR map has a value, the dense map keeps it up to the smoothing (docs/algorithm.md 6d).
    kept = (esr > 0) & (np.abs(dense.astype(np.int32) - esr.astype(np.int32)) <= 256)  # within 1 px
    assert kept.sum() > 0.8 * (esr > 0).sum()


def test_detect_eval_dense_through_the_cache(firmware_bin, dataset, tmp_path):
    cfg = config(tmp_path, "d", '[detect]\ninput = "dense"\n')
    cache, js1, js2 = tmp_path / "cache", tmp_path / "a.json", tmp_path / "b.json"
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--config", cfg, "--disparity-cache", cache,
            "--max-disparity", "32", "--limit", "1", "--json", js1)
    assert p.returncode == 0, p.stderr
    assert "densified" in p.stdout
    a = json.loads(js1.read_text())
    assert a["input"] == "dense" and a["densify_ms_per_frame"] >= 0
    # The cache records and holds the sparse ESR map.
    assert (cache / "disparity_map.txt").read_text().strip() == "esr"
    assert "[densify]\nenabled = false" in (cache / "matcher_config.toml").read_text()
    cached = cv2.imread(str(cache / "000000_10.png"), cv2.IMREAD_UNCHANGED)
    assert (cached == 0).sum() > 0.05 * cached.size
    # Read back from the cache: the same detections as the fresh run.
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--config", cfg, "--disparity-cache", cache,
            "--max-disparity", "32", "--limit", "1", "--json", js2)
    assert p.returncode == 0, p.stderr
    b = json.loads(js2.read_text())
    assert [f["detections"] for f in a["frames"]] == [f["detections"] for f in b["frames"]]
    # ... and the same as `detect`, which reads the matcher's own disp_final: densify after the cache is
    # the matcher's densify stage.
    _, boxes = detect(firmware_bin, dataset, cfg, tmp_path / "det")
    ev = [[*d["box"], round(d["distance_m"], 6)] for d in b["frames"][0]["detections"]]
    assert sorted(ev) == sorted(boxes)
    # The sparse input on the same cache gives other detections or at least reports the ESR input.
    e = config(tmp_path, "e", '[detect]\ninput = "esr"\n')
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--config", e, "--disparity-cache", cache,
            "--max-disparity", "32", "--limit", "1", "--json", js2)
    assert p.returncode == 0, p.stderr
    assert json.loads(js2.read_text())["input"] == "esr" and "ESR (sparse)" in p.stdout


def test_cache_ignores_densify_but_not_the_matcher(firmware_bin, dataset, tmp_path):
    # The cache holds ESR maps, which [densify] does not change: a cache whose recorded [densify]
    # differs (e.g. made before a [densify] field existed) is used; one whose [cost] differs is refused.
    cache = tmp_path / "cache"
    args = ("detect-eval", "--dataset", dataset, "--disparity-cache", cache, "--max-disparity", "32", "--limit", "1")
    assert run(firmware_bin, *args).returncode == 0
    mc = cache / "matcher_config.toml"
    text = mc.read_text()
    assert "\ninterpolate_max_diff = " in text
    mc.write_text(text.replace("\ninterpolate_max_diff = ", "\nold_densify_field = "))
    p = run(firmware_bin, *args)
    assert p.returncode == 0, p.stderr
    mc.write_text(text.replace("\nalpha = ", "\nalpha = 0.9\nwas_alpha = "))
    p = run(firmware_bin, *args)
    assert p.returncode == 2 and "different matcher config" in p.stderr, (p.stdout, p.stderr)


def test_cache_holding_another_map_is_refused(firmware_bin, dataset, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "disparity_map.txt").write_text("dense\n")
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--disparity-cache", cache, "--limit", "1")
    assert p.returncode == 2, (p.stdout, p.stderr)
    assert "holds the 'dense' map" in p.stderr


def test_bad_input_value_is_rejected(firmware_bin, dataset, tmp_path):
    p = run(firmware_bin, "detect-eval", "--dataset", dataset, "--oracle-disparity", "--limit", "1", "--config",
            config(tmp_path, "x", '[detect]\ninput = "sparse"\n'))
    assert p.returncode == 2 and "detect.input" in p.stderr, p.stderr
