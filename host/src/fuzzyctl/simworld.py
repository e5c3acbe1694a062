"""Obstacles of a simulator run record (`run.json` "world"), as the firmware's `sim::ObstacleSpec`."""
from __future__ import annotations

import math
from typing import Any


def obstacle_state(o: dict[str, Any], t: float) -> tuple[float, float, float, float]:
    """(x, y, vx, vy) of a recorded obstacle at time t [s].

    An obstacle moves with ("vx", "vy") from ("x", "y") at t = 0; a solid mover (suite worlds with
    `[loop] suite_movers = "stop"` or `"slide"`, session 27) changes its velocity at each of its
    "turns" [t, vx, vy] (a stop is a turn to 0, 0).
    """
    x, y = o.get("x", 0.0), o.get("y", 0.0)
    vx, vy = o.get("vx", 0.0), o.get("vy", 0.0)
    t0 = 0.0
    for tk, kx, ky in o.get("turns", []):
        if tk > t:
            break
        x, y = x + (tk - t0) * vx, y + (tk - t0) * vy
        t0, vx, vy = tk, kx, ky
    return x + (t - t0) * vx, y + (t - t0) * vy, vx, vy


def obstacle_moves(o: dict[str, Any]) -> bool:
    """Whether a recorded obstacle ever moves (a start velocity, or a turn to a nonzero one)."""
    return bool(o.get("vx", 0.0) or o.get("vy", 0.0) or any(k[1] or k[2] for k in o.get("turns", [])))


def wrap_angle(a: float) -> float:
    """a [rad] wrapped into [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi
