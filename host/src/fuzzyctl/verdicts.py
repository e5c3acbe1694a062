"""The robot loop's moving-test verdicts of simulator run records, scored against the world's truth.

Session 46's oracle rungs (docs/robot.md "Session 46") showed that the loop loses most where its moving test
(``robot::moving_test``; each confirmed track's verdict is logged as ``tracks[].moving_test`` in ``frames.jsonl``)
calls a mover's track static or a static obstacle's track a mover: with the true labels instead of the test
(``--oracle mover-labels``) seeds 164-165 gave 195 of 200 goals and 3 contacts against the defaults' 188 and 9. A
suite takes minutes per seed; this scores the verdicts of recorded runs in seconds, so a change of the test can be
judged offline first.

Two tables:

- **verdicts per track-frame**: every confirmed track with a verdict whose last measurement lies within
  ``match_m`` of a world circle's rim (the nearest), split by whether that obstacle moves, all of them and those
  whose estimate is within ``near_m`` of the robot — the share of each verdict ("mover", "few hits", ...);
- **coverage of known movers near the robot**: every frame and every moving obstacle within ``near_m`` (2 m) of
  the robot that some confirmed track has covered before — is there now a confirmed track whose estimate lies
  within the obstacle's radius + ``cover_m``, and what is the best one's verdict? "no track" splits into in view
  and out of view (the camera's half field of view from the record's calibration).

Matching is by circle only (the suite's obstacles; boxes and walls are static and left out, as in
``track-errors``).
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import Any

from .contacts import half_fov_rad
from .errors import FatalError
from .runreport import load_run
from .simworld import obstacle_moves, obstacle_state, wrap_angle
from .trackerrors import world_circles


def _shares(c: Counter) -> dict[str, Any]:
    n = sum(c.values())
    return {"n": n, "share": {k: v / n for k, v in c.most_common()} if n else {}}


def _truth_of(tr: dict[str, Any], circles: list[dict[str, Any]], t: float, match_m: float) -> str | None:
    """"mover" / "static": the world circle nearest the track's last measurement (by its rim, at that
    measurement's time), when within match_m; None otherwise."""
    t_meas = t - tr.get("age_s", 0.0)
    best = None
    for o in circles:
        ox, oy, _, _ = obstacle_state(o, t_meas)
        d = math.hypot(ox - tr["last"][0], oy - tr["last"][1]) - o["radius"]
        if best is None or d < best[0]:
            best = (d, o)
    if best is None or best[0] > match_m:
        return None
    return "mover" if obstacle_moves(best[1]) else "static"


FEATURE_COLUMNS = ("record", "frame", "t", "track", "truth", "robot_dist", "verdict", "static_meas", "static_support",
                   "hits", "speed", "vx", "vy", "tx", "ty", "life_s", "end_var", "age_s", "r", "t1x", "t1y", "t2x",
                   "t2y", "vac1", "vac1_cells", "vac2", "vac2_cells")


MOVING_TEST_DEFAULTS = {"min_hits": 4, "min_speed_mps": 0.04, "max_age_s": 8.0, "min_travel_m": 0.3,
                        "travel_sigmas": 0.0, "window_s": 0.0, "window_travel_m": 0.1, "direction_near_m": 1.5,
                        "vacated_share": 0.0, "vacated_window_s": 1.0, "vacated_near_m": 3.0, "vacated_min_cells": 8}


def moving_test(row: dict[str, Any], **params: float) -> str:
    """``robot::moving_test`` (firmware/robot/planner/progress.cpp) on one feature row: its verdict with the
    given parameters ([loop] moving_*; the defaults of common/config/default.toml otherwise). window_s may be
    0, 1 or 2 (the recorded recent travels), vacated_window_s 1 or 2 (the recorded "vacated" shares, session 53).
    Scores variants of the test on recorded inputs."""
    p = {**MOVING_TEST_DEFAULTS, **params}
    verdict = _moving_test_before_vacated(row, p)
    if verdict in ("short travel", "travel within noise", "direction") and p["vacated_share"] > 0:
        key = {1.0: "vac1", 2.0: "vac2"}.get(float(p["vacated_window_s"]))
        if key is None:
            raise FatalError(f"vacated_window_s: the records hold the vacated share over 1 s and 2 s only, "
                             f"not {p['vacated_window_s']}")
        if (row["robot_dist"] <= p["vacated_near_m"] and row[key + "_cells"] >= p["vacated_min_cells"]
                and row[key] >= p["vacated_share"]):
            return "mover"
    return verdict


def _moving_test_before_vacated(row: dict[str, Any], p: dict[str, float]) -> str:
    if row["static_meas"]:
        return "static measurement"
    if row["static_support"]:
        return "static support"
    if row["hits"] < p["min_hits"]:
        return "few hits"
    speed = math.hypot(row["vx"], row["vy"])
    if speed < p["min_speed_mps"]:
        return "slow"
    if row["age_s"] > p["max_age_s"]:
        return "old"
    dist = math.hypot(row["tx"], row["ty"])
    if dist < p["min_travel_m"] or dist < p["min_speed_mps"] * row["life_s"]:
        return "short travel"
    if p["travel_sigmas"] > 0 and dist < p["travel_sigmas"] * math.sqrt(row["end_var"]):
        return "travel within noise"
    if p["direction_near_m"] > 0 and row["robot_dist"] <= p["direction_near_m"]:
        return "mover"
    if p["window_s"] > 0:
        key = {1.0: "t1", 2.0: "t2"}.get(float(p["window_s"]))
        if key is None:
            raise FatalError(f"window_s: the records hold the travel over 1 s and 2 s only, not {p['window_s']}")
        rx, ry = row[key + "x"], row[key + "y"]
        rd = math.hypot(rx, ry)
        if rd >= p["window_travel_m"]:
            return "mover" if rx * row["vx"] + ry * row["vy"] >= 0.7 * rd * speed else "direction"
    return "mover" if row["tx"] * row["vx"] + row["ty"] * row["vy"] >= 0.7 * dist * speed else "direction"


def feature_rows(run_dirs: list[Path], match_m: float = 0.3) -> list[dict[str, Any]]:
    """One row per confirmed track-frame with a verdict and its inputs (``tracks[].mt``, recorded since session
    47): the moving test's inputs, its verdict and the truth ("mover", "static" or "none" when no world circle
    lies within match_m of its last measurement) — to score variants of the test offline."""
    rows: list[dict[str, Any]] = []
    for run_dir in run_dirs:
        run, frames = load_run(run_dir)
        circles = world_circles(run, Path(run_dir))
        for f in frames:
            for tr in f.get("tracks", []):
                mt = tr.get("mt")
                if not tr.get("confirmed") or mt is None:
                    continue
                vx, vy = mt["vel"]
                rows.append({"record": Path(run_dir).name, "frame": f["frame"], "t": f["t"], "track": tr["id"],
                             "truth": _truth_of(tr, circles, f["t"], match_m) or "none",
                             "robot_dist": mt["robot_dist"], "verdict": tr["moving_test"],
                             "static_meas": int(mt["static_meas"]), "static_support": int(mt["static_support"]),
                             "hits": mt["hits"], "speed": math.hypot(vx, vy), "vx": vx, "vy": vy,
                             "tx": mt["travel"][0], "ty": mt["travel"][1], "life_s": mt["life_s"],
                             "end_var": mt["end_var"], "age_s": tr.get("age_s", 0.0), "r": tr["r"],
                             "t1x": mt["travel_1s"][0], "t1y": mt["travel_1s"][1],
                             "t2x": mt["travel_2s"][0], "t2y": mt["travel_2s"][1],
                             # the "vacated" evidence (session 53; records before it have none): the share
                             # of the cells left that the map has seen through since, and their number
                             **{key: value for w in (1, 2) for key, value in _vacated(mt, w)}})
    if not rows:
        raise FatalError("no confirmed track in these records carries the moving test's inputs (tracks[].mt, "
                         "recorded since session 47): record with a current `fuzzystereo sim suite --record DIR`")
    return rows


def _vacated(mt: dict[str, Any], w: int) -> tuple[tuple[str, float], tuple[str, int]]:
    free, cells = mt.get(f"vac_{w}s", [0, 0])
    return (f"vac{w}", free / cells if cells else 0.0), (f"vac{w}_cells", cells)


def verdicts(run_dirs: list[Path], match_m: float = 0.3, near_m: float = 2.0, cover_m: float = 0.3) -> dict[str, Any]:
    """Both tables over all records; FatalError naming a record without truth or without verdicts."""
    if not run_dirs:
        raise FatalError("no run record given")
    per = {k: Counter() for k in ("mover", "mover_near", "static", "static_near")}
    cover: Counter = Counter()
    any_verdict = False
    for run_dir in run_dirs:
        run, frames = load_run(run_dir)
        circles = world_circles(run, Path(run_dir))
        half_fov = half_fov_rad(run)
        movers = [o for o in circles if obstacle_moves(o)]
        covered_before: set[int] = set()
        for f in frames:
            if "true_pose" not in f or "tracks" not in f:
                raise FatalError(f"{Path(run_dir) / 'frames.jsonl'}: frame {f.get('frame')} has no 'true_pose'/'tracks'")
            x, y, th = f["true_pose"]
            t = f["t"]
            confirmed = [tr for tr in f["tracks"] if tr.get("confirmed")]
            for tr in confirmed:
                verdict = tr.get("moving_test")
                if verdict is None:
                    continue
                any_verdict = True
                kind = _truth_of(tr, circles, t, match_m)
                if kind is None:
                    continue
                per[kind][verdict] += 1
                if math.hypot(tr["p"][0] - x, tr["p"][1] - y) <= near_m:
                    per[kind + "_near"][verdict] += 1
            for o in movers:
                ox, oy, _, _ = obstacle_state(o, t)
                on = [tr for tr in confirmed if math.hypot(tr["p"][0] - ox, tr["p"][1] - oy) <= o["radius"] + cover_m]
                seen_before = o["id"] in covered_before
                if on:
                    covered_before.add(o["id"])
                if not seen_before or math.hypot(ox - x, oy - y) > near_m:
                    continue
                if on:
                    verdict_of = [tr.get("moving_test", "?") for tr in on]
                    cover["mover track" if "mover" in verdict_of else f"only: {verdict_of[0]}"] += 1
                else:
                    bearing = abs(wrap_angle(math.atan2(oy - y, ox - x) - th))
                    cover["no track, in view" if bearing < half_fov else "no track, out of view"] += 1
    if not any_verdict:
        raise FatalError("no track in these records carries a moving-test verdict (tracks[].moving_test, "
                         "recorded since session 41): record with a current `fuzzystereo sim suite --record DIR`")
    return {"records": len(run_dirs), "match_m": match_m, "near_m": near_m, "cover_m": cover_m,
            "verdicts": {k: _shares(c) for k, c in per.items()}, "mover_coverage": _shares(cover)}
