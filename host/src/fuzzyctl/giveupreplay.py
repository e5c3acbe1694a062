"""What ``[loop] give_up_after_s`` would have done on recorded runs (docs/robot.md "Session 44").

The rule (``robot::GiveUpMonitor``, firmware/robot/planner/progress.cpp): the robot stops for good, a safe
stop, once it has not got ``stuck_progress_m`` closer to the goal (straight line from its own pose estimate)
for ``give_up_after_s`` and its planner has found no path at least once since that last progress. It only
*ends* runs: until it holds, a run with the rule is the run without it. So its effect on a recorded run is
read off the frame log exactly, up to the braking at the end: the first frame where it holds, against how and
when the run ended. This is how the session-44 value was chosen; a robot's own records (no simulator truth
needed) show when the rule would have stopped it.

Frames give ``t`` [s], ``pose`` (the loop's estimate: what the firmware measures progress with) and
``status`` (the planner's, ``blocked`` = no path). ``run.json`` gives the goal and the result.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import Any

from .errors import FatalError
from .runreport import expand_run_dirs, load_run, load_run_config

#: Effects of the rule on one run, in the order of the summary table.
EFFECTS = ("arrival lost", "safe stop gained", "contact avoided", "earlier safe stop", "timeout -> stop", "ended earlier")


def first_give_up(frames: list[dict[str, Any]], goal: tuple[float, float], after_s: float,
                  progress_m: float) -> float | None:
    """Time [s] of the first frame at which the rule holds (GiveUpMonitor::update, step for step), else None."""
    if after_s <= 0:
        return None
    best = math.inf
    best_t = 0.0
    blocked_since_best = False
    for f in frames:
        t, pose = float(f["t"]), f["pose"]
        dist = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
        if dist < best - progress_m:
            best, best_t, blocked_since_best = dist, t, False
        blocked_since_best = blocked_since_best or f.get("status") == "blocked"
        if blocked_since_best and t - best_t >= after_s - 1e-9:
            return t
    return None


def _solvable(result: dict[str, Any]) -> bool:
    shortest = result.get("shortest_m")
    return isinstance(shortest, (int, float)) and math.isfinite(shortest)


def effect(result: dict[str, Any], fire_t: float | None, contact_margin_s: float = 1.0) -> str | None:
    """How the rule firing at fire_t changes a run that ended with `result` (None: not at all). A contact
    counts as avoided only when the rule held `contact_margin_s` before it (the robot needs time to brake)."""
    end = float(result.get("time_s", math.inf))
    if fire_t is None or fire_t >= end - 1e-9:
        return None
    status = str(result.get("status", ""))
    solvable = _solvable(result)
    if result.get("collided") or result.get("struck") or status in ("collision", "struck"):
        return "contact avoided" if fire_t <= end - contact_margin_s else None
    if status == "reached" or result.get("reached"):
        return "arrival lost"
    if status in ("blocked_stop", "no_progress_stop"):
        return "earlier safe stop" if not solvable else "ended earlier"
    if status == "timeout":
        return "timeout -> stop" if solvable else "safe stop gained"
    return "ended earlier"


def give_up_replay(run_dirs: list[Path], afters: list[float], contact_margin_s: float = 1.0) -> dict[str, Any]:
    """Per value of give_up_after_s: the runs it would have ended, and how (EFFECTS)."""
    if not afters or any(a <= 0 for a in afters):
        raise FatalError(f"--after: give_up_after_s values must be > 0 s (got {afters})")
    dirs = expand_run_dirs(list(run_dirs))
    runs = []
    for d in dirs:
        run, frames = load_run(d)
        if "goal" not in run or "result" not in run:
            raise FatalError(f"{d / 'run.json'}: no 'goal' or 'result' (a run record of an older firmware?)")
        if frames and "pose" not in frames[0]:
            raise FatalError(f"{d / 'frames.jsonl'}: frames without 'pose'")
        progress_m = float(load_run_config(d)["loop"]["stuck_progress_m"])
        runs.append((d, run, frames, progress_m))
    table = []
    for after in afters:
        counts: Counter[str] = Counter()
        changed = []
        for d, run, frames, progress_m in runs:
            goal = (float(run["goal"][0]), float(run["goal"][1]))
            t = first_give_up(frames, goal, after, progress_m)
            e = effect(run["result"], t, contact_margin_s)
            if e is None:
                continue
            counts[e] += 1
            changed.append({"run": d.name, "effect": e, "give_up_s": t, "status": run["result"].get("status"),
                            "end_s": run["result"].get("time_s")})
        table.append({"after_s": after, "counts": {k: counts.get(k, 0) for k in EFFECTS}, "changed": changed})
    return {"records": len(runs), "contact_margin_s": contact_margin_s, "afters": table}
