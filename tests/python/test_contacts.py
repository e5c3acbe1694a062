"""fuzzyctl contacts: the contacts of run records traced against the simulated truth and classified."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from fuzzyctl.cli import main
from fuzzyctl.contacts import contacts, trace_contact
from fuzzyctl.errors import FatalError

CALIB = {"baseline_m": 0.12, "cx": 159.5, "cy": 89.5, "focal_px": 134.25594098836478}  # half view 50 deg


def _record(tmp: Path, name: str, obstacle: dict, cmd: tuple[float, float], result: dict,
            track_until: float | None = None, track_mover: bool = False) -> Path:
    """A robot standing at the origin facing +x for 2 s (frames every 0.2 s) with a fixed command,
    one obstacle, a track on the obstacle's true position until `track_until`."""
    from fuzzyctl.simworld import obstacle_state

    d = tmp / name
    d.mkdir()
    run = {"calib": CALIB, "robot_radius_m": 0.15, "world": {"obstacles": [obstacle]},
           "result": {"time_s": 2.0, **result}}
    (d / "run.json").write_text(json.dumps(run))
    lines = []
    for k in range(10):
        t = 0.2 * k
        x, y, vx, vy = obstacle_state(obstacle, t)
        tracks = []
        if track_until is not None and t <= track_until:
            tracks.append({"id": 7, "confirmed": True, "mover": track_mover, "p": [x, y], "v": [vx, vy]})
        lines.append(json.dumps({"frame": k, "t": t, "pose": [0.0, 0.0, 0.0], "true_pose": [0.0, 0.0, 0.0],
                                "cmd": list(cmd), "tracks": tracks}))
    (d / "frames.jsonl").write_text("\n".join(lines) + "\n")
    return d


def _mover_from(bearing_deg: float, speed: float = 0.2) -> dict:
    """A mover that reaches the robot's surface at t = 2 s from `bearing_deg`, along the bearing."""
    b = math.radians(bearing_deg)
    r0 = 0.15 + 0.2 - 0.01 + speed * 2.0  # contact (1 cm overlap) at t = 2
    return {"id": 3, "shape": "circle", "radius": 0.2, "x": r0 * math.cos(b), "y": r0 * math.sin(b),
            "vx": -speed * math.cos(b), "vy": -speed * math.sin(b)}


def test_side_mover_with_the_robot_turning_into_it(tmp_path: Path) -> None:
    # From the left at 80 deg (outside the 50 deg half view), never in view: "never seen"; the same
    # mover seen at first (it came along the heading, then turned): "side, turning into it".
    d = _record(tmp_path, "a", _mover_from(80.0), (0.3, 0.5), {"collided": True}, track_until=1.0)
    r = trace_contact(d)
    assert r is not None and r["class"] == "never seen" and r["mover"]
    assert r["bearing_deg"] == pytest.approx(80.0, abs=1.0)
    o = _mover_from(80.0)
    o["x"], o["y"], o["vx"], o["vy"] = 1.2, 0.0, 0.0, 0.0
    # at rest ahead until 0.8 s, then moving to the contact point at 80 deg
    cx, cy = 0.34 * math.cos(math.radians(80)), 0.34 * math.sin(math.radians(80))
    vx, vy = (cx - 1.2) / 1.2, cy / 1.2
    o["turns"] = [[0.8, vx, vy]]
    d2 = _record(tmp_path, "b", o, (0.3, 0.5), {"collided": True}, track_until=0.7, track_mover=True)
    r2 = trace_contact(d2)
    assert r2["class"] == "side, turning into it"
    assert r2["seen_s_before"] is not None and r2["seen_s_before"] > 0.1
    assert r2["tracked_s_before"] == pytest.approx(1.4, abs=1e-6)
    assert r2["track"]["mover"] is True
    # the same, turning away from it: "side"
    d3 = _record(tmp_path, "c", o, (0.3, -0.5), {"collided": True})
    assert trace_contact(d3)["class"] == "side"


def test_static_in_view_standing_and_no_contact(tmp_path: Path) -> None:
    static = {"id": 1, "shape": "circle", "radius": 0.2, "x": 0.34, "y": 0.0}
    assert trace_contact(_record(tmp_path, "s", static, (0.3, 0.0), {"collided": True}))["class"] == "static"
    ahead = _mover_from(10.0)
    assert trace_contact(_record(tmp_path, "v", ahead, (0.3, 0.0), {"collided": True}))["class"] == "in view"
    stand = _mover_from(10.0)
    assert trace_contact(_record(tmp_path, "t", stand, (0.0, 0.0), {"collided": True}))["class"] == "struck standing"
    none = _record(tmp_path, "n", static, (0.3, 0.0), {"collided": False, "struck": False})
    assert trace_contact(none) is None
    # a contact with nothing round nearby: a box or a wall
    far = {"id": 2, "shape": "circle", "radius": 0.2, "x": 3.0, "y": 0.0}
    r = trace_contact(_record(tmp_path, "w", far, (0.3, 0.0), {"collided": True}))
    assert r["obstacle"] is None and r["class"] == "static"


def test_ground_ahead_share_over_the_last_second(tmp_path: Path) -> None:
    static = {"id": 1, "shape": "circle", "radius": 0.2, "x": 0.34, "y": 0.0}
    d = _record(tmp_path, "g", static, (0.3, 0.0), {"collided": True})
    assert trace_contact(d)["ground_ahead_min_pct"] is None  # a record without the field
    lines = [json.loads(x) for x in (d / "frames.jsonl").read_text().splitlines()]
    for f, pct in zip(lines, [5.0, 90.0, 90.0, 90.0, 90.0, 80.0, 70.0, 30.0, 12.5, 40.0]):
        f["ground_ahead_pct"] = pct
    (d / "frames.jsonl").write_text("\n".join(json.dumps(f) for f in lines) + "\n")
    # frames from t = 1.0 s on (the contact at 2.0 s): 80, 70, 30, 12.5, 40; the 5 % at t = 0 is older
    assert trace_contact(d)["ground_ahead_min_pct"] == pytest.approx(12.5)
    assert trace_contact(d, ground_window_s=2.0)["ground_ahead_min_pct"] == pytest.approx(5.0)


def test_cli_expands_a_suite_record_directory(tmp_path: Path, capsys) -> None:
    suite = tmp_path / "rec"
    suite.mkdir()
    _record(suite, "suite-1-0", _mover_from(10.0), (0.3, 0.0), {"collided": True})
    _record(suite, "suite-1-1", {"id": 1, "shape": "circle", "radius": 0.2, "x": 3.0, "y": 1.0}, (0.3, 0.0),
            {"collided": False})
    out = tmp_path / "c.json"
    assert main(["contacts", str(suite), "--json", str(out)]) == 0
    j = json.loads(out.read_text())
    assert j["records"] == 2 and len(j["contacts"]) == 1 and j["classes"]["in view"] == 1
    assert "suite-1-0" in capsys.readouterr().out
    assert contacts([suite / "suite-1-1"])["contacts"] == []
    # the suite report names each contact's class beside the run
    assert main(["suite-report", str(suite)]) == 0
    assert "in view, +10 deg" in (suite / "suite.html").read_text()


def test_a_record_without_truth_is_named(tmp_path: Path) -> None:
    d = tmp_path / "replay"
    d.mkdir()
    (d / "run.json").write_text(json.dumps({"source": "replay:x", "result": {"collided": True}}))
    (d / "frames.jsonl").write_text(json.dumps({"t": 0.0, "true_pose": [0, 0, 0]}) + "\n")
    with pytest.raises(FatalError, match="world.obstacles"):
        trace_contact(d)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["contacts", str(empty)]) != 0


def test_planned_tells_whether_the_planner_had_the_obstacle(tmp_path: Path) -> None:
    # A mover from 60 deg, tracked throughout; the planner's list holds a disc on it (kind n) until
    # 1.2 s and then only an unrelated map cell far away: in the last second (frames 1.0-1.8 s) 2 of 5
    # frames covered it, the last one by nothing. A record without planner lists gives None.
    from fuzzyctl.simworld import obstacle_state

    o = _mover_from(60.0)
    d = _record(tmp_path, "p", o, (0.3, 0.0), {"collided": True}, track_until=2.0)
    assert trace_contact(d)["planned"] is None
    frames = [json.loads(line) for line in (d / "frames.jsonl").read_text().splitlines()]
    for f in frames:
        x, y, _, _ = obstacle_state(o, f["t"])
        if f["t"] <= 1.2 + 1e-9:
            f["plan_obstacles"], f["plan_kinds"] = [[x + 0.1, y, 0.2], [5.0, 5.0, 0.03]], "nm"
        else:
            f["plan_obstacles"], f["plan_kinds"] = [[5.0, 5.0, 0.03]], "m"
        for tr in f["tracks"]:
            tr["moving_test"] = "direction"  # the loop's verdict on the track (session 41 records)
    (d / "frames.jsonl").write_text("\n".join(json.dumps(f) for f in frames) + "\n")
    c = trace_contact(d)
    assert c["planned"] == {"frames": 5, "covered": 2, "last_kinds": ""}
    assert c["track"]["moving_test"] == "direction"
    # the CLI shows it
    assert main(["contacts", str(d)]) in (0, None)
