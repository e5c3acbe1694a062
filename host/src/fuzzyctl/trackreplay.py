"""``fuzzyctl track-replay``: the tracker's Kalman filter re-run on run records (reference/tracker.py).

Two uses:

- **the cross-language check of the filter**: with each record's own ``[tracker]`` settings the
  reference's states must equal the firmware's recorded ones (``agreement``: the largest position and
  velocity difference over every track on every frame);
- **what-if on the same measurements**: ``--set tracker.KEY=VALUE`` changes the filter's settings and
  reports issue 5's tracking figures for the replayed filter beside the firmware's and the raw
  measurements' (simulator records: the truth is in run.json) — the same selection as ``fuzzyctl
  track-errors``: every update whose measurement lies within ``match_m`` of a moving obstacle.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

from .errors import FatalError
from .reference.tracker import KalmanParams, replay_frames
from .runreport import load_run, load_run_config
from .trackerrors import has_truth, mover_truth, quantile, world_circles

#: The [tracker] fields the filter reads; others (association, deletion) cannot change in a replay.
FILTER_KEYS = tuple(KalmanParams.__dataclass_fields__)
#: The one measurement setting a replay can change: the floor of R ([loop] meas_sigma_floor_m), upwards only.
FLOOR_KEY = "loop.meas_sigma_floor_m"


def parse_overrides(items: tuple[str, ...] | list[str]) -> dict[str, Any]:
    """``tracker.KEY=VALUE`` items (or ``loop.meas_sigma_floor_m=VALUE``; VALUE in TOML syntax) checked against
    the schema, as {"section.key": value}; FatalError naming a bad item, a key the replay cannot change, or a
    value out of range."""
    from .config import load_schema, validate

    schema = load_schema()
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not (key.startswith("tracker.") or key == FLOOR_KEY):
            raise FatalError(f"--set {item!r}: expected tracker.KEY=VALUE (KEY one of {', '.join(FILTER_KEYS)}) "
                             f"or {FLOOR_KEY}=VALUE")
        section, name = key.split(".", 1)
        if section == "tracker" and name not in FILTER_KEYS:
            raise FatalError(f"--set {item!r}: a replay re-runs the filter only; KEY must be one of {', '.join(FILTER_KEYS)}")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError as exc:
            raise FatalError(f"--set {item!r}: the value is not TOML ({exc})") from None
        out[key] = validate({section: {name: value}}, schema, f"--set {key}")[section][name]
    return out


def _rms(v: list[float]) -> float | None:
    return math.sqrt(sum(x * x for x in v) / len(v)) if v else None


def track_replay(run_dirs: list[Path], overrides: dict[str, Any] | None = None, match_m: float = 0.5) -> dict[str, Any]:
    """Replay every record; the agreement with the firmware and (with truth) the movers' figures. ``overrides``:
    {"tracker.KEY" | "loop.meas_sigma_floor_m": value}, as parse_overrides returns them."""
    if not run_dirs:
        raise FatalError("no run record given")
    overrides = overrides or {}
    max_dp = max_dv = 0.0
    states = updates = 0
    raw_e: list[float] = []
    ref_e: list[float] = []
    fw_e: list[float] = []
    ref_v10: list[float] = []
    nis: list[float] = []
    fw_v10: list[float] = []
    truth = True
    for run_dir in run_dirs:
        run, frames = load_run(run_dir)
        cfg = load_run_config(Path(run_dir))
        tracker = dict(cfg["tracker"])
        tracker.update({k.split(".", 1)[1]: v for k, v in overrides.items() if k.startswith("tracker.")})
        kp = KalmanParams.from_values(tracker)
        if kp.coast_decay_s > 0 and tracker.get("coast_decay_unseen_only", False):
            raise FatalError(f"{run_dir}: [tracker] coast_decay_unseen_only decays a track's velocity only outside the "
                             "camera's view, which the record does not hold; the replay cannot follow it "
                             "(replay with --set tracker.coast_decay_s=0, or record without it)")
        floor, own = overrides.get(FLOOR_KEY, 0.0), float(cfg["loop"]["meas_sigma_floor_m"])
        if floor and floor < own:
            raise FatalError(f"--set {FLOOR_KEY}={floor}: below the record's own floor {own} m ({run_dir}/config.toml); "
                             "its variances already hold that floor, so a replay can only raise it")
        replayed = replay_frames(frames, kp, str(Path(run_dir) / "frames.jsonl"), floor * floor)
        circles = world_circles(run, Path(run_dir)) if has_truth(run) else None
        truth = truth and circles is not None
        for s in replayed:
            states += 1
            max_dp = max(max_dp, math.hypot(s.ref_p[0] - s.fw_p[0], s.ref_p[1] - s.fw_p[1]))
            max_dv = max(max_dv, math.hypot(s.ref_v[0] - s.fw_v[0], s.ref_v[1] - s.fw_v[1]))
            if not s.updated:
                continue
            updates += 1
            if s.nis is not None and s.hits > 3:  # confirmed tracks past their first velocity estimates
                nis.append(s.nis)
            if circles is None:
                continue
            mt = mover_truth(circles, s.t, *s.raw, match_m)
            if mt is None:
                continue
            ox, oy, tvx, tvy = mt
            raw_e.append(math.hypot(s.raw[0] - ox, s.raw[1] - oy))
            ref_e.append(math.hypot(s.ref_p[0] - ox, s.ref_p[1] - oy))
            fw_e.append(math.hypot(s.fw_p[0] - ox, s.fw_p[1] - oy))
            if s.hits >= 10:
                ref_v10.append(math.hypot(s.ref_v[0] - tvx, s.ref_v[1] - tvy))
                fw_v10.append(math.hypot(s.fw_v[0] - tvx, s.fw_v[1] - tvy))
    return {
        "records": len(run_dirs),
        "overrides": overrides,
        "agreement": {"states": states, "updates": updates, "max_pos_diff_m": max_dp, "max_vel_diff_mps": max_dv},
        # Filter consistency, no truth needed (a real robot's records too): the position NIS of the updates of
        # tracks past their 3rd hit; a consistent filter gives mean 2 and 95 % below 5.99 (chi-square, 2 dof).
        "nis": {"n": len(nis), "mean": sum(nis) / len(nis) if nis else None,
                "median": quantile(nis, 0.5) if nis else None,
                "share_above_5_99": sum(1 for v in nis if v > 5.991) / len(nis) if nis else None},
        "movers": None if not truth else {
            "n": len(raw_e),
            "raw_pos_rmse_m": _rms(raw_e),
            "firmware_pos_rmse_m": _rms(fw_e),
            "replay_pos_rmse_m": _rms(ref_e),
            "vel_after10_n": len(ref_v10),
            "firmware_vel_after10_p95_mps": quantile(fw_v10, 0.95) if fw_v10 else None,
            "replay_vel_after10_p95_mps": quantile(ref_v10, 0.95) if ref_v10 else None,
            "replay_vel_after10_median_mps": quantile(ref_v10, 0.5) if ref_v10 else None,
        },
    }
