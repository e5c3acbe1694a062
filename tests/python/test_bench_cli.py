"""`fuzzystereo bench`: the interleaved timing table and its JSON (no timing is asserted: speed is a
benchmark figure, never a unit-test pass/fail condition)."""

from __future__ import annotations

import json
import os
import subprocess

import pytest

pytestmark = pytest.mark.firmware


def test_bench_on_the_builtin_pair_writes_table_and_json(firmware_bin, tmp_path):
    out = tmp_path / "bench.json"
    # No datasets at the default location: bench falls back to its built-in synthetic pair.
    env = dict(os.environ, FUZZYSTEREO_DATASETS=str(tmp_path / "none"))
    r = subprocess.run([str(firmware_bin), "bench", "--repeats", "1", "--json", str(out)],
                       capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    assert "interleaved" in r.stdout
    for line in ("segmentation", "cost", "opencv sgbm 3-way", "ratio fuzzystereo/sgbm"):
        assert line in r.stdout
    j = json.loads(out.read_text())
    assert [run["threads"] for run in j["runs"]][0] == 1
    for run in j["runs"]:
        assert run["fuzzystereo_ms"] > 0 and run["sgbm_ms"] > 0 and run["bm_ms"] > 0
        assert set(run["stages_ms"]) == {"gradient", "segmentation", "cost", "wta", "lrcheck", "esr", "densify"}
        assert run["ratio_fuzzystereo_sgbm"] > 0
    assert j["radiometric"] == "none" and j["boundary_refined"] is False
    assert "boundary refinement off" in r.stdout


def test_bench_times_a_mismatched_pair(firmware_bin, tmp_path):
    # --radiometric distorts the right image as eval does; the darker right view trips the gain trigger, and
    # the matcher then runs the boundary refinement (docs/algorithm.md 4b): bench says so and times it.
    out = tmp_path / "bench.json"
    env = dict(os.environ, FUZZYSTEREO_DATASETS=str(tmp_path / "none"))
    r = subprocess.run([str(firmware_bin), "bench", "--repeats", "1", "--radiometric", "gain", "--json", str(out)],
                       capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    assert "radiometric 'gain' applied" in r.stdout and "compensated the gain" in r.stdout
    assert "boundary refinement on" in r.stdout
    j = json.loads(out.read_text())
    assert j["radiometric"] == "gain" and j["boundary_refined"] is True
    bad = subprocess.run([str(firmware_bin), "bench", "--radiometric", "fog"], capture_output=True, text=True, timeout=60)
    assert bad.returncode != 0 and "fog" in bad.stderr and "noise" in bad.stderr


def test_bench_rejects_zero_repeats(firmware_bin):
    r = subprocess.run([str(firmware_bin), "bench", "--repeats", "0"], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert "--repeats" in (r.stderr + r.stdout)


def test_bench_names_a_missing_dataset_directory(firmware_bin, tmp_path):
    missing = tmp_path / "nope"
    r = subprocess.run([str(firmware_bin), "bench", "--dataset", str(missing)], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2
    assert str(missing) in r.stderr
