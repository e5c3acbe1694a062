"""fuzzyctl track-errors: measurement and velocity errors of run records against the simulated truth."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from fuzzyctl.cli import main
from fuzzyctl.errors import FatalError
from fuzzyctl.trackerrors import track_errors


def _record(tmp: Path, name: str, bearing_deg: float, inward_m: float, fwd_m: float, v_err: float,
            moving: bool) -> Path:
    """One obstacle at range 2 m and the given bearing from a robot at the origin facing +x; every
    frame a track updated with a measurement `inward_m` towards the image centre and `fwd_m` further,
    and a velocity off by `v_err` along x."""
    d = tmp / name
    d.mkdir()
    b = math.radians(bearing_deg)
    vx, vy = (0.2, 0.0) if moving else (0.0, 0.0)
    ox, oy = 2.0 * math.cos(b), 2.0 * math.sin(b)
    run = {"world": {"obstacles": [
        {"id": 0, "shape": "circle", "radius": 0.2, "x": ox, "y": oy, "vx": vx, "vy": vy},
        {"id": 1, "shape": "box", "x": 9.0, "y": 9.0},
    ]}, "result": {}}
    (d / "run.json").write_text(json.dumps(run))
    side = 1.0 if oy >= 0 else -1.0
    lines = []
    for k in range(10):
        t = 0.2 * k
        px, py = ox + vx * t + fwd_m, oy + vy * t - side * inward_m
        tr = {"id": 1, "confirmed": True, "hits": 5 + k, "age_s": 0.0, "last": [px, py], "p": [px, py],
              "v": [vx + v_err, vy], "r": 0.2}
        lines.append(json.dumps({"frame": k, "t": t, "true_pose": [0.0, 0.0, 0.0], "tracks": [tr]}))
    (d / "frames.jsonl").write_text("\n".join(lines) + "\n")
    return d


def test_signed_errors_per_bearing_band_and_velocity_errors(tmp_path: Path) -> None:
    a = _record(tmp_path, "a", 5.0, 0.02, 0.05, 0.1, moving=True)
    b = _record(tmp_path, "b", -35.0, 0.09, 0.01, 0.3, moving=False)
    r = track_errors([a, b])
    rows = {tuple(row["bearing_deg"]): row for row in r["measurement"]}
    assert rows[(0, 10)]["n"] == 10
    assert rows[(0, 10)]["lateral_outward_median_m"] == pytest.approx(-0.02, abs=1e-9)
    assert rows[(0, 10)]["forward_median_m"] == pytest.approx(0.05, abs=1e-9)
    assert rows[(0, 10)]["abs_median_m"] == pytest.approx(math.hypot(0.02, 0.05), abs=1e-9)
    # bearing -35 deg: "inward" is towards +y, the outward sign still makes it negative
    assert rows[(30, 40)]["n"] == 10
    assert rows[(30, 40)]["lateral_outward_median_m"] == pytest.approx(-0.09, abs=1e-9)
    assert rows[(10, 20)]["n"] == 0 and rows[(10, 20)]["abs_median_m"] is None
    assert r["velocity"]["moving"]["median_mps"] == pytest.approx(0.1, abs=1e-9)
    assert r["velocity"]["static"]["median_mps"] == pytest.approx(0.3, abs=1e-9)


def test_movers_filtered_against_raw_and_velocity_from_the_10th_hit(tmp_path: Path) -> None:
    # _record puts the track's state on its measurement (filtered = raw); move the state halfway back to
    # the truth and check that the filtered error is half the raw one. Hits run 5..14: from the 10th on,
    # 5 of the 10 frames count for the velocity.
    a = _record(tmp_path, "a", 5.0, 0.0, 0.1, 0.2, moving=True)
    lines = [json.loads(x) for x in (a / "frames.jsonl").read_text().splitlines()]
    for f in lines:
        tr = f["tracks"][0]
        tr["p"] = [tr["last"][0] - 0.05, tr["last"][1]]
    (a / "frames.jsonl").write_text("\n".join(json.dumps(f) for f in lines) + "\n")
    b = _record(tmp_path, "b", 5.0, 0.0, 0.1, 0.3, moving=False)  # static: not in the movers' figures
    m = track_errors([a, b])["movers"]
    assert m["n"] == 10
    assert m["raw_pos_rmse_m"] == pytest.approx(0.1, abs=1e-9)
    assert m["filt_pos_rmse_m"] == pytest.approx(0.05, abs=1e-9)
    assert m["vel_after10_n"] == 5
    assert m["vel_after10_median_mps"] == pytest.approx(0.2, abs=1e-9)


def test_cli_prints_tables_and_writes_json(tmp_path: Path, capsys) -> None:
    a = _record(tmp_path, "a", 25.0, 0.05, 0.0, 0.0, moving=True)
    out = tmp_path / "e.json"
    assert main(["track-errors", str(a), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "20-30" in text and "-0.050" in text
    assert json.loads(out.read_text())["records"] == 1


def test_a_record_without_truth_is_named(tmp_path: Path) -> None:
    d = tmp_path / "replay"
    d.mkdir()
    (d / "run.json").write_text(json.dumps({"source": "replay:x", "result": {}}))
    (d / "frames.jsonl").write_text("")
    with pytest.raises(FatalError, match="world.obstacles"):
        track_errors([d])


def test_solid_mover_follows_its_turns():
    from fuzzyctl.simworld import obstacle_state

    o = {"x": 1.0, "y": 2.0, "vx": 0.5, "vy": 0.0, "turns": [[2.0, 0.0, 0.5], [4.0, 0.0, 0.0]]}
    assert obstacle_state(o, 1.0) == (1.5, 2.0, 0.5, 0.0)
    assert obstacle_state(o, 3.0) == (2.0, 2.5, 0.0, 0.5)
    assert obstacle_state(o, 10.0) == (2.0, 3.0, 0.0, 0.0)
    walker = {k: v for k, v in o.items() if k != "turns"}  # pass-through mover: walks on
    assert obstacle_state(walker, 10.0) == (6.0, 2.0, 0.5, 0.0)
