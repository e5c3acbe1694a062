"""Tracker measurement and velocity errors of simulator run records, against the world's truth.

``fuzzystereo sim suite --record DIR`` and ``fuzzystereo run --source sim:... --record DIR`` write
run records (docs/formats.md, "Run record") whose ``run.json`` holds the simulated world's
obstacles (position at t = 0, constant velocity) and whose ``frames.jsonl`` holds, per frame, the
true robot pose and every track (``last``: the measurement it was updated with this frame, ``p``,
``v``: the filter's state, ``age_s``: time since its last measurement).

Two figures, both matched to the nearest round obstacle of the world at the frame's time:

- **measurement error** of each track updated this frame (``age_s == 0``), split into the component
  along the camera's forward axis and the lateral one, signed *outward* (positive = away from the
  image centre), in bands of the obstacle's bearing. A systematic negative lateral error growing
  with the bearing is the signature of a centre placed behind the front along the camera axis
  instead of along the ray (docs/robot.md "Session 12");
- **velocity error** ``|v_track - v_true|`` of confirmed tracks updated this frame with at least
  ``min_hits`` hits, for moving and for static obstacles (a static obstacle's track should read 0).

And issue 5's tracking targets on the vision pipeline's own measurements (``targets``): for every
track updated this frame whose measurement lies within ``match_m`` of a *moving* obstacle, the
filtered position's error against the raw measurement's (RMSE over those frames), and the velocity
error of such tracks from their 10th hit on ("within 0.1 m/s after 10 frames").
"""

from __future__ import annotations

import math
import statistics
from pathlib import Path
from typing import Any

from .errors import FatalError
from .runreport import load_run
from .simworld import obstacle_state

#: Bands of |bearing| [deg] of the measurement-error table.
BEARING_BANDS = ((0, 10), (10, 20), (20, 30), (30, 40), (40, 90))


def has_truth(run: dict[str, Any]) -> bool:
    """Whether a run record holds the simulated world (only simulator runs do)."""
    world = run.get("world")
    return isinstance(world, dict) and "obstacles" in world


def world_circles(run: dict[str, Any], run_dir: Path) -> list[dict[str, Any]]:
    world = run.get("world")
    if not isinstance(world, dict) or "obstacles" not in world:
        raise FatalError(f"{run_dir / 'run.json'}: no 'world.obstacles' (only simulator runs have the truth)")
    return [o for o in world["obstacles"] if o.get("shape") == "circle"]


def _nearest(circles: list[dict[str, Any]], t: float, x: float, y: float
             ) -> tuple[float, dict[str, Any], float, float] | None:
    """(distance, obstacle, its x, its y) of the circle nearest (x, y) at time t, or None."""
    best = None
    for o in circles:
        ox, oy, _, _ = obstacle_state(o, t)
        d = math.hypot(ox - x, oy - y)
        if best is None or d < best[0]:
            best = (d, o, ox, oy)
    return best


def mover_truth(circles: list[dict[str, Any]], t: float, x: float, y: float, match_m: float
                ) -> tuple[float, float, float, float] | None:
    """Issue 5's tracking targets on vision measurements count a measurement at (x, y) when it lies within
    match_m of the nearest circle and that circle moves: (x, y, vx, vy) of that obstacle at time t, else None.
    One definition for ``track-errors`` and ``track-replay``, so their figures are comparable."""
    hit = _nearest(circles, t, x, y)
    return _if_moving(hit, t) if hit is not None and hit[0] <= match_m else None


def _if_moving(hit: tuple[float, dict[str, Any], float, float], t: float) -> tuple[float, float, float, float] | None:
    """(x, y, vx, vy) of a _nearest hit's obstacle at time t when it moves, else None."""
    _, _, vx, vy = obstacle_state(hit[1], t)
    return (hit[2], hit[3], vx, vy) if math.hypot(vx, vy) > 0.01 else None


def quantile(v: list[float], q: float) -> float:
    s = sorted(v)
    return s[int(q * (len(s) - 1))] if s else float("nan")


def track_errors(run_dirs: list[Path], match_m: float = 0.5, velocity_match_m: float = 0.3,
                 min_hits: int = 4) -> dict[str, Any]:
    """The two error tables over all records; FatalError naming a record without truth."""
    if not run_dirs:
        raise FatalError("no run record given")
    meas: dict[tuple[int, int], list[tuple[float, float, float]]] = {b: [] for b in BEARING_BANDS}
    vel: dict[str, list[float]] = {"moving": [], "static": []}
    filt_sq: list[float] = []
    raw_sq: list[float] = []
    vel10: list[float] = []
    for run_dir in run_dirs:
        run, frames = load_run(run_dir)
        circles = world_circles(run, Path(run_dir))
        for f in frames:
            if "true_pose" not in f or "tracks" not in f:
                raise FatalError(f"{Path(run_dir) / 'frames.jsonl'}: frame {f.get('frame')} has no 'true_pose'/'tracks'")
            rx, ry, yaw = f["true_pose"]
            t = float(f["t"])
            c, s = math.cos(yaw), math.sin(yaw)
            for tr in f["tracks"]:
                if tr.get("age_s", 1.0) > 1e-6:
                    continue
                px, py = tr["last"]
                hit = _nearest(circles, t, px, py)
                if hit is not None and hit[0] <= match_m:
                    _, o, ox, oy = hit
                    fwd, lat = c * (ox - rx) + s * (oy - ry), -s * (ox - rx) + c * (oy - ry)
                    bearing = abs(math.degrees(math.atan2(lat, fwd)))
                    ex, ey = px - ox, py - oy
                    e_fwd, e_lat = c * ex + s * ey, -s * ex + c * ey
                    outward = e_lat if lat >= 0 else -e_lat
                    for band in BEARING_BANDS:
                        if band[0] <= bearing < band[1]:
                            meas[band].append((outward, e_fwd, math.hypot(ex, ey)))
                            break
                    mt = _if_moving(hit, t)  # the selection of mover_truth, on the hit already found
                    if mt is not None and "p" in tr:
                        _, _, tvx, tvy = mt
                        raw_sq.append(ex * ex + ey * ey)
                        filt_sq.append((tr["p"][0] - ox) ** 2 + (tr["p"][1] - oy) ** 2)
                        if tr.get("hits", 0) >= 10 and "v" in tr:
                            vel10.append(math.hypot(tr["v"][0] - tvx, tr["v"][1] - tvy))
                if not tr.get("confirmed") or tr.get("hits", 0) < min_hits:
                    continue
                hit = _nearest(circles, t, *tr["p"])
                if hit is None or hit[0] > velocity_match_m:
                    continue
                o = hit[1]
                _, _, vx, vy = obstacle_state(o, t)
                kind = "moving" if math.hypot(vx, vy) > 0.01 else "static"
                vel[kind].append(math.hypot(tr["v"][0] - vx, tr["v"][1] - vy))
    out: dict[str, Any] = {"records": len(run_dirs), "measurement": [], "velocity": {}}
    for band, rows in meas.items():
        out["measurement"].append({
            "bearing_deg": list(band), "n": len(rows),
            "lateral_outward_median_m": statistics.median(r[0] for r in rows) if rows else None,
            "forward_median_m": statistics.median(r[1] for r in rows) if rows else None,
            "abs_median_m": statistics.median(r[2] for r in rows) if rows else None,
        })
    for kind, v in vel.items():
        out["velocity"][kind] = {"n": len(v), "median_mps": statistics.median(v) if v else None,
                                 "p90_mps": quantile(v, 0.9) if v else None}
    out["movers"] = {
        "n": len(raw_sq),
        "filt_pos_rmse_m": math.sqrt(sum(filt_sq) / len(filt_sq)) if filt_sq else None,
        "raw_pos_rmse_m": math.sqrt(sum(raw_sq) / len(raw_sq)) if raw_sq else None,
        "vel_after10_n": len(vel10),
        "vel_after10_rms_mps": math.sqrt(sum(v * v for v in vel10) / len(vel10)) if vel10 else None,
        "vel_after10_median_mps": statistics.median(vel10) if vel10 else None,
        "vel_after10_p95_mps": quantile(vel10, 0.95) if vel10 else None,
    }
    return out
