"""`fuzzyctl verdicts`: the loop's moving-test verdicts scored against the simulated world (session 46)."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys

import pytest

from fuzzyctl.errors import FatalError
from fuzzyctl.verdicts import moving_test, verdicts


def _record(tmp_path, frames, world=None):
    d = tmp_path / "run"
    d.mkdir()
    world = world or [
        # a mover walking +x at 0.2 m/s from (2, 0), and a static post at (1, 1.5)
        {"id": 0, "shape": "circle", "radius": 0.2, "x": 2.0, "y": 0.0, "vx": 0.2, "vy": 0.0},
        {"id": 1, "shape": "circle", "radius": 0.15, "x": 1.0, "y": 1.5, "vx": 0.0, "vy": 0.0},
    ]
    (d / "run.json").write_text(json.dumps({"calib": {"cx": 159.5, "focal_px": 134.3}, "world": {"obstacles": world}}))
    (d / "frames.jsonl").write_text("\n".join(json.dumps(f) for f in frames) + "\n")
    return d


def _track(tid, p, verdict, age=0.0, last=None):
    return {"id": tid, "confirmed": True, "p": list(p), "last": list(last or p), "age_s": age, "moving_test": verdict}


def test_shares_per_kind_and_coverage_of_known_movers(tmp_path):
    frames = [
        # t = 0: the mover's track calls it a mover, the post's track calls it a mover too (a false mover)
        {"t": 0.0, "true_pose": [0.5, 0.0, 0.0],
         "tracks": [_track(1, (2.2, 0.0), "mover"), _track(2, (1.15, 1.5), "mover")]},
        # t = 1: the mover (now at 2.2, 0) is held back by "few hits"; the post is "static measurement"
        {"t": 1.0, "true_pose": [0.5, 0.0, 0.0],
         "tracks": [_track(3, (2.4, 0.0), "few hits"), _track(2, (1.15, 1.5), "static measurement")]},
        # t = 2: the robot has turned away (heading pi): the mover (2.4, 0) is out of view and its track has
        # drifted 1 m off; no track covers it
        {"t": 2.0, "true_pose": [0.5, 0.0, math.pi],
         "tracks": [_track(3, (3.4, 0.0), "few hits", age=1.0, last=(2.4, 0.0))]},
    ]
    r = verdicts([_record(tmp_path, frames)])
    v = r["verdicts"]
    assert v["mover"]["n"] == 3  # the t = 2 track's last measurement (t = 1, at 2.4 m) lies on the mover then
    assert v["mover"]["share"] == pytest.approx({"mover": 1 / 3, "few hits": 2 / 3})
    assert v["static"]["share"] == pytest.approx({"mover": 0.5, "static measurement": 0.5})
    assert v["mover_near"]["n"] == 2  # the drifted estimate (3.4 m) is beyond 2 m of the robot
    c = r["mover_coverage"]
    # t = 0 first covers the mover (not counted: "tracked before" starts after it); t = 1 covered by a few-hits
    # track; t = 2 no track, out of view
    assert c["n"] == 2
    assert c["share"] == pytest.approx({"only: few hits": 0.5, "no track, out of view": 0.5})


def test_records_without_truth_or_verdicts_are_refused(tmp_path):
    d = _record(tmp_path, [{"t": 0.0, "true_pose": [0, 0, 0], "tracks": [{"id": 1, "confirmed": True, "p": [2, 0],
                                                                              "last": [2, 0], "age_s": 0.0}]}])
    with pytest.raises(FatalError, match="moving_test"):
        verdicts([d])
    (d / "run.json").write_text(json.dumps({"calib": {}}))
    with pytest.raises(FatalError, match="world.obstacles"):
        verdicts([d])
    with pytest.raises(FatalError, match="no run record"):
        verdicts([])


def test_cli_on_a_firmware_record(firmware_bin, tmp_path):
    # A real suite scenario with a mover (164-10): the command reads the firmware's own record.
    rec = tmp_path / "rec"
    p = subprocess.run([str(firmware_bin), "sim", "suite", "--count", "100", "--seed", "164", "--only", "10",
                        "--record", str(rec)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    out = tmp_path / "v.json"
    feats = tmp_path / "f.csv"
    p = subprocess.run([sys.executable, "-m", "fuzzyctl", "verdicts", str(rec), "--json", str(out),
                        "--features", str(feats)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "moving-test verdicts" in p.stdout
    r = json.loads(out.read_text())
    assert r["records"] == 1
    assert r["verdicts"]["mover"]["n"] > 0 and r["verdicts"]["static"]["n"] > 0
    assert sum(r["verdicts"]["mover"]["share"].values()) == pytest.approx(1.0)
    # The feature rows (tracks[].mt, session 47): the host's port of robot::moving_test gives every recorded
    # verdict back from the recorded inputs — what makes offline scores of variants of the test meaningful.
    with open(feats, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) >= r["verdicts"]["mover"]["n"] + r["verdicts"]["static"]["n"]
    assert {row["truth"] for row in rows} >= {"mover", "static"}
    typed = [{k: (v if k in ("record", "truth", "verdict") else float(v)) for k, v in row.items()} for row in rows]
    for x in typed:
        assert moving_test(x) == x["verdict"], x
    # a variant moves verdicts: without a hit minimum no row is "few hits"
    assert any(x["verdict"] == "few hits" for x in typed)
    assert not any(moving_test(x, min_hits=0) == "few hits" for x in typed)


def test_port_of_the_vacated_override_on_a_firmware_record(firmware_bin, tmp_path):
    # [loop] moving_vacated_share (session 53) on: the port gives the firmware's verdicts back from the logged
    # "vacated" counts, and the override makes movers of tracks the defaults called otherwise.
    cfg = tmp_path / "vac.toml"
    cfg.write_text("[loop]\nmoving_vacated_share = 0.3\n")
    rec = tmp_path / "rec"
    p = subprocess.run([str(firmware_bin), "sim", "suite", "--count", "100", "--seed", "164", "--only", "10",
                        "--config", str(cfg), "--record", str(rec)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    feats = tmp_path / "f.csv"
    p = subprocess.run([sys.executable, "-m", "fuzzyctl", "verdicts", str(rec), "--features", str(feats)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    with open(feats, newline="") as fh:
        typed = [{k: (v if k in ("record", "truth", "verdict") else float(v)) for k, v in row.items()}
                 for row in csv.DictReader(fh)]
    assert typed
    for x in typed:
        assert moving_test(x, vacated_share=0.3) == x["verdict"], x
    overridden = [x for x in typed if x["verdict"] == "mover" and moving_test(x) != "mover"]
    assert overridden, "the override changed no verdict of this mover scenario"
