"""Where the contacts of simulator runs come from: the obstacle hit and what the robot knew of it.

``fuzzystereo sim suite --record DIR`` writes one run record per scenario (docs/formats.md, "Run
record"); a run that ended in a contact (``result.collided`` or ``result.struck``) is traced back
over its ``frames.jsonl`` against the simulated world's truth (``run.json`` ``world.obstacles``,
solid movers with their turns, :func:`fuzzyctl.simworld.obstacle_state`):

- the **obstacle hit**: the round obstacle nearest the robot's true pose at the contact (the run's
  last frame, advanced to ``result.time_s``), static or moving, and its surface clearance (a
  clearance above ``max_clearance_m`` means the nearest round obstacle was not the one hit: a box or
  wall, reported as such);
- its **bearing** from the robot's heading at the last frame and whether that lies inside the
  camera's horizontal field of view (from ``run.json`` ``calib``: width = 2 cx + 1);
- what the robot **did**: moving (|commanded linear| >= ``moving_mps``), and whether it was turning
  towards the obstacle's side (angular command of the bearing's sign, above ``turn_radps``);
- what it **knew**: when the obstacle was last inside the view (within ``view_range_m``), when a
  track was last within ``track_match_m`` of it, and that track's flags (confirmed, mover), speed and
  moving-test verdict (``moving_test``: "mover", or the first condition that failed, e.g. "direction");
- what it **planned with**: in the frames of the last ``ground_window_s`` that carry the planner's
  obstacles (``plan_obstacles``, ``plan_kinds``: every 10th frame by default, every frame with
  ``--plan-every 1``), how many had a planner disc overlapping the obstacle's true disc, and the kinds
  of those discs at the last such frame (docs/robot.md "Session 41": in most contacts nothing);
  and the least share of the ground band ahead the detector explained in the last ``ground_window_s``
  (low: the robot drove at something the camera could not see; docs/robot.md "Session 32").

Each contact gets one class (first that applies):

``static``                the obstacle hit does not move (a perception or planning miss);
``never seen``            a mover that never entered the view;
``struck standing``       the robot stood (the simulator's own "struck" verdict, or not moving);
``in view``               the obstacle was inside the view at the last frame;
``side, turning into it`` outside the view, the robot moving and turning towards its side;
``side``                  outside the view, the robot moving straight or turning away.

The tool replaces the throw-away scripts of docs/robot.md sessions 23-29 that did this by hand.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import Any

from .errors import FatalError
from .runreport import load_run
from .simworld import obstacle_moves, obstacle_state, wrap_angle

CLASSES = ("static", "never seen", "struck standing", "in view", "side, turning into it", "side")


def half_fov_rad(run: dict[str, Any]) -> float:
    """Half the horizontal field of view of the recorded camera (pinhole: atan((cx + 0.5) / f))."""
    c = run.get("calib")
    if not isinstance(c, dict) or "cx" not in c or "focal_px" not in c:
        raise FatalError("run.json: no 'calib' with 'cx' and 'focal_px' (needed for the camera's view)")
    return math.atan2(float(c["cx"]) + 0.5, float(c["focal_px"]))


def ground_ahead_min_pct(frames: list[dict[str, Any]], t_from: float) -> float | None:
    """The least share of the ground band ahead that the detector explained (frames.jsonl
    ``ground_ahead_pct``, docs/robot.md "Session 32") over the frames from ``t_from`` on; None when
    the record has no such field (records before session 32)."""
    vals = [float(f["ground_ahead_pct"]) for f in frames if "ground_ahead_pct" in f and float(f["t"]) >= t_from]
    return min(vals) if vals else None


def planned_cover(frames: list[dict[str, Any]], o: dict[str, Any], t_from: float) -> dict[str, Any] | None:
    """Whether the planner had the obstacle ``o``: over the frames from ``t_from`` on that carry
    ``plan_obstacles`` ([x, y, r] discs) and ``plan_kinds`` (one letter per disc), the number of them
    with a disc overlapping the obstacle's true disc at that frame's time, and the kinds covering it
    at the last of them ("" = nothing). None when no frame in the window carries planner obstacles."""
    n = covered = 0
    last_kinds = ""
    for f in frames:
        if float(f["t"]) < t_from or "plan_obstacles" not in f:
            continue
        ox, oy, _, _ = obstacle_state(o, float(f["t"]))
        kinds = str(f.get("plan_kinds", ""))
        hit = sorted({kinds[i] if i < len(kinds) else "?" for i, (x, y, r) in enumerate(f["plan_obstacles"])
                      if math.hypot(x - ox, y - oy) < float(r) + float(o["radius"])})
        n += 1
        covered += bool(hit)
        last_kinds = "".join(hit)
    return None if n == 0 else {"frames": n, "covered": covered, "last_kinds": last_kinds}


def trace_contact(run_dir: Path, max_clearance_m: float = 0.1, moving_mps: float = 0.05, turn_radps: float = 0.05,
                  view_range_m: float = 6.0, track_match_m: float = 0.5,
                  ground_window_s: float = 1.0) -> dict[str, Any] | None:
    """The contact of one run record, or None when the run ended without one."""
    run, frames = load_run(run_dir)
    res = run.get("result", {})
    if not (res.get("collided") or res.get("struck")):
        return None
    world = run.get("world")
    if not isinstance(world, dict) or "obstacles" not in world:
        raise FatalError(f"{Path(run_dir) / 'run.json'}: no 'world.obstacles' (only simulator runs have the truth)")
    if not frames:
        raise FatalError(f"{Path(run_dir) / 'frames.jsonl'}: no frames")
    hf = half_fov_rad(run)
    radius = float(run.get("robot_radius_m", 0.0))
    t_end = float(res.get("time_s", frames[-1]["t"]))
    last = frames[-1]
    rx, ry, rth = last["true_pose"]
    # The last logged frame is up to one period before the contact: advance the pose along the
    # commanded twist (a few centimetres) so that the nearest obstacle is the one touched.
    v, w = (last.get("cmd") or [0.0, 0.0])[:2]
    dt = max(0.0, t_end - float(last["t"]))
    cx, cy = rx + v * dt * math.cos(rth + 0.5 * w * dt), ry + v * dt * math.sin(rth + 0.5 * w * dt)
    best: tuple[float, dict[str, Any]] | None = None
    for o in world["obstacles"]:
        if o.get("shape") != "circle":
            continue
        ox, oy, _, _ = obstacle_state(o, t_end)
        clr = math.hypot(ox - cx, oy - cy) - float(o["radius"]) - radius
        if best is None or clr < best[0]:
            best = (clr, o)
    out: dict[str, Any] = {"run": Path(run_dir).name, "time_s": t_end, "status": res.get("status"),
                           "robot_speed_mps": v, "robot_turn_radps": w,
                           "ground_ahead_min_pct": ground_ahead_min_pct(frames, t_end - ground_window_s)}
    if best is None or best[0] > max_clearance_m:
        out.update({"obstacle": None, "class": "static", "note": "not a round obstacle (box or wall)"})
        return out
    clr, o = best
    ox, oy, ovx, ovy = obstacle_state(o, t_end)
    bearing = wrap_angle(math.atan2(oy - ry, ox - rx) - rth)
    mover = obstacle_moves(o)
    first_view = last_view = None
    last_track: dict[str, Any] | None = None
    last_track_t = None
    for f in frames:
        t = float(f["t"])
        fx, fy, fth = f["true_pose"]
        px, py, _, _ = obstacle_state(o, t)
        b = wrap_angle(math.atan2(py - fy, px - fx) - fth)
        if abs(b) < hf and math.hypot(px - fx, py - fy) < view_range_m:
            first_view = t if first_view is None else first_view
            last_view = t
        for tr in f.get("tracks", []):
            if math.hypot(tr["p"][0] - px, tr["p"][1] - py) < track_match_m:
                last_track, last_track_t = tr, t
    standing = bool(res.get("struck")) or abs(v) < moving_mps
    in_view = abs(bearing) < hf
    turning_into = abs(w) > turn_radps and (w > 0) == (bearing > 0)
    if not mover:
        cls = "static"
    elif first_view is None:
        cls = "never seen"
    elif standing:
        cls = "struck standing"
    elif in_view:
        cls = "in view"
    elif turning_into:
        cls = "side, turning into it"
    else:
        cls = "side"
    out.update({
        "class": cls, "obstacle": o.get("id"), "mover": mover, "obstacle_speed_mps": math.hypot(ovx, ovy),
        "clearance_m": clr, "bearing_deg": math.degrees(bearing), "in_view": in_view,
        "seen_s_before": None if last_view is None else t_end - last_view,
        "tracked_s_before": None if last_track_t is None else t_end - last_track_t,
        "planned": planned_cover(frames, o, t_end - ground_window_s),
        "track": None if last_track is None else {
            "id": last_track.get("id"), "confirmed": bool(last_track.get("confirmed")),
            "mover": bool(last_track.get("mover")), "speed_mps": math.hypot(*last_track["v"]),
            # the loop's moving-test verdict (records from session 41 on): "mover" or the condition that failed
            "moving_test": last_track.get("moving_test")},
    })
    return out


def contacts(run_dirs: list[Path], **kw: Any) -> dict[str, Any]:
    """Every contact of the given run records (directories without one are counted, not listed)."""
    rows = []
    for d in run_dirs:
        r = trace_contact(Path(d), **kw)
        if r is not None:
            rows.append(r)
    counts = Counter(r["class"] for r in rows)
    return {"records": len(run_dirs), "contacts": rows, "classes": {c: counts.get(c, 0) for c in CLASSES}}
