"""Float reference of the tracker's Kalman filter, replayed on a run record (``fuzzyctl track-replay``).

The firmware's tracker (``firmware/robot/tracking``) filters every obstacle with a constant-velocity
Kalman filter in the paper's form: state [p, v], ``F = [[I, dt I], [0, I]]`` (eq. 28), ``Q`` from a
white-noise acceleration, ``H = I`` with the velocity measured as the finite difference of two
position measurements (eq. 31-32), the initial covariance of eq. (30), and the maneuver switch of
session 31 (docs/robot.md): ``Q`` at ``accel_sigma_steady_mps2`` while the fading mean of the
position NIS stays below ``maneuver_nis``, ``accel_sigma_mps2`` while it is above.

A run record (``fuzzystereo run|sim suite --record DIR``) logs, every frame, each track's filtered
state (``p``, ``v``), its last measurement at full precision (``last``) with the variance the filter
gave it (``mvar``, since session 43) and the time since it (``age_s``: 0 on a frame that updated it).
Association, confirmation and deletion are the firmware's; this module re-runs only the filter, track
by track, on the measurements the firmware associated. With the record's own ``[tracker]`` settings
the replayed states equal the firmware's to floating-point rounding — 1e-10 m, up to ~1e-5 m right after
an update that follows seconds of coasting, whose covariance (10^3 m^2) makes it ill-conditioned — the
cross-language check of the filter (``tests/python/test_track_replay.py``); with other settings it answers "what would the filter
have estimated from the same measurements" — the tracking targets of issue 5 on the vision pipeline's
own measurements (docs/robot.md "Session 43") without re-running the closed loop. The loop itself would
have driven differently with another filter (the planner reads the tracks), which a replay does not show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import FatalError


@dataclass(frozen=True)
class KalmanParams:
    """The ``[tracker]`` fields the filter reads (common/config/schema.toml)."""

    accel_sigma_mps2: float = 0.5
    accel_sigma_steady_mps2: float = 0.15
    maneuver_nis: float = 4.0
    maneuver_fade: float = 0.7
    init_vel_sigma_mps: float = 5.0
    velocity_measurement: bool = True
    coast_decay_s: float = 0.0

    @classmethod
    def from_values(cls, tracker: dict[str, Any]) -> "KalmanParams":
        """The fields from a ``[tracker]`` table; coast_decay_s (session 47) is 0 when a record's older config
        lacks it."""
        optional = {"coast_decay_s"}
        return cls(**{k: type(getattr(cls, k))(tracker[k]) for k in cls.__dataclass_fields__
                      if k in tracker or k not in optional})


def transition(dt: float) -> np.ndarray:
    """eq. (28): F = [[I, dt I], [0, I]]."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt
    return f


def transition_damped(dt: float, tau: float) -> np.ndarray:
    """[tracker] coast_decay_s (outside the paper; CvKalman::F_damped): the velocity decays as e^{-dt/tau}, the
    position moves by its integral."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = -tau * math.expm1(-dt / tau)
    f[2, 2] = f[3, 3] = math.exp(-dt / tau)
    return f


def process_noise(dt: float, accel_sigma: float) -> np.ndarray:
    """Q = G G^T sa^2 with G = [dt^2/2 I; dt I] (the velocity change over dt is the random input)."""
    s2 = accel_sigma * accel_sigma
    q11, q12, q22 = s2 * dt ** 4 / 4.0, s2 * dt ** 3 / 2.0, s2 * dt * dt
    q = np.zeros((4, 4))
    q[0, 0] = q[1, 1] = q11
    q[0, 2] = q[2, 0] = q[1, 3] = q[3, 1] = q12
    q[2, 2] = q[3, 3] = q22
    return q


@dataclass
class TrackFilter:
    """One track's filter state and the bookkeeping the update reads."""

    x: np.ndarray
    P: np.ndarray
    hits: int = 1
    last_meas: np.ndarray = field(default_factory=lambda: np.zeros(2))
    last_var: float = 0.0
    last_t: float = 0.0
    nis_mean: float = 2.0  # the chi-square mean with 2 degrees of freedom (the firmware's Track::nis_mean)
    maneuvering: bool = False

    @classmethod
    def init(cls, p: np.ndarray, var: float, t: float, kp: KalmanParams) -> "TrackFilter":
        """eq. (30): position at the measurement, zero velocity, velocity std init_vel_sigma_mps."""
        v0 = kp.init_vel_sigma_mps ** 2
        return cls(x=np.array([p[0], p[1], 0.0, 0.0]), P=np.diag([var, var, v0, v0]), last_meas=p.copy(),
                   last_var=var, last_t=t)

    def q_level(self, kp: KalmanParams) -> float:
        switching = kp.accel_sigma_steady_mps2 > 0.0
        return kp.accel_sigma_steady_mps2 if switching and not self.maneuvering else kp.accel_sigma_mps2

    def predict(self, dt: float, kp: KalmanParams, coasting: bool = False) -> None:
        """eq. (26)/(29), B u = 0; a coasting track (no measurement at the previous frame) with coast_decay_s > 0
        predicts with the damped transition."""
        f = transition_damped(dt, kp.coast_decay_s) if coasting and kp.coast_decay_s > 0 else transition(dt)
        self.x = f @ self.x
        self.P = f @ self.P @ f.T + process_noise(dt, self.q_level(kp))

    def position_nis(self, p: np.ndarray, var: float) -> float:
        """Normalised innovation squared of a position measurement against the predicted state: chi-square with
        2 degrees of freedom (mean 2) while the model and R fit the measurements."""
        s = self.P[:2, :2] + var * np.eye(2)
        nu = p - self.x[:2]
        return float(nu @ np.linalg.solve(s, nu))

    def update(self, p: np.ndarray, var: float, t: float, dt_pred: float, kp: KalmanParams) -> float:
        """The maneuver switch, then eq. (31)-(32) with H = I (z = [p, finite-difference v]) or H = [I 0].
        Returns the position NIS before the update."""
        nis = self.position_nis(p, var)
        if kp.accel_sigma_steady_mps2 > 0.0:
            self.nis_mean = kp.maneuver_fade * self.nis_mean + (1.0 - kp.maneuver_fade) * nis
            now = self.nis_mean > kp.maneuver_nis
            if now and not self.maneuvering and dt_pred > 0.0:
                hi, lo = kp.accel_sigma_mps2, kp.accel_sigma_steady_mps2
                self.P = self.P + process_noise(dt_pred, math.sqrt(max(0.0, hi * hi - lo * lo)))
            self.maneuvering = now
        dtm = t - self.last_t
        if kp.velocity_measurement and self.hits >= 1 and dtm > 1e-6:
            z = np.concatenate([p, (p - self.last_meas) / dtm])
            r = np.zeros((4, 4))
            r[0, 0] = r[1, 1] = var
            r[2, 2] = r[3, 3] = (var + self.last_var) / (dtm * dtm)
            r[0, 2] = r[2, 0] = r[1, 3] = r[3, 1] = var / dtm
            k = self.P @ np.linalg.inv(self.P + r)
            self.x = self.x + k @ (z - self.x)
            self.P = self.P - k @ self.P
        else:
            h = np.zeros((2, 4))
            h[0, 0] = h[1, 1] = 1.0
            s = h @ self.P @ h.T + var * np.eye(2)
            k = self.P @ h.T @ np.linalg.inv(s)
            self.x = self.x + k @ (p - h @ self.x)
            self.P = self.P - k @ h @ self.P
        self.P = 0.5 * (self.P + self.P.T)
        self.hits += 1
        self.last_meas = p.copy()
        self.last_var = var
        self.last_t = t
        return nis


@dataclass(frozen=True)
class ReplayedState:
    """One track on one frame: the firmware's recorded state and the reference's."""

    t: float
    track: int
    updated: bool        # this frame's measurement updated it (age_s == 0)
    hits: int            # after this frame
    raw: tuple[float, float]
    fw_p: tuple[float, float]
    fw_v: tuple[float, float]
    ref_p: tuple[float, float]
    ref_v: tuple[float, float]
    nis: float | None = None  # position NIS of this frame's update (None: no update, or the track's first)


def replay_frames(frames: list[dict[str, Any]], kp: KalmanParams, source: str = "frames.jsonl",
                  var_floor_m2: float = 0.0) -> list[ReplayedState]:
    """The filter re-run on a record's frames (each frame is one tracker step, as in the loop): tracks
    are predicted to every frame, updated on frames with age_s == 0, started when their id first
    appears, dropped when it no longer does. ``var_floor_m2``: each measurement's variance is at least this
    (``[loop] meas_sigma_floor_m`` squared; exact for floors at or above the record's own, which its
    ``mvar`` already holds). FatalError naming the frame when a track lacks ``mvar``."""
    out: list[ReplayedState] = []
    filters: dict[int, TrackFilter] = {}
    t_prev: float | None = None
    for f in frames:
        if "tracks" not in f or "t" not in f:
            raise FatalError(f"{source}: frame {f.get('frame')} has no 't'/'tracks'")
        t = float(f["t"])
        dt_pred = t - t_prev if t_prev is not None and t > t_prev else 0.0
        if dt_pred > 0.0:
            for tf in filters.values():
                tf.predict(dt_pred, kp, coasting=t_prev is not None and tf.last_t < t_prev - 1e-9)
        if t_prev is None or dt_pred > 0.0:
            t_prev = t
        seen: set[int] = set()
        for tr in f["tracks"]:
            tid = int(tr["id"])
            seen.add(tid)
            updated = float(tr.get("age_s", 1.0)) <= 1e-9
            if updated and "mvar" not in tr:
                raise FatalError(f"{source}: frame {f.get('frame')}, track {tid}: no 'mvar' (the measurement variance is "
                                 "recorded since session 43; re-record the run with this firmware)")
            p = np.array(tr["last"], dtype=float)
            nis = None
            if tid not in filters:
                if not updated:
                    continue  # appeared coasting: recorded before this replay could start it
                filters[tid] = TrackFilter.init(p, max(float(tr["mvar"]), var_floor_m2), t, kp)
            elif updated:
                nis = filters[tid].update(p, max(float(tr["mvar"]), var_floor_m2), t, dt_pred, kp)
            tf = filters[tid]
            out.append(ReplayedState(t, tid, updated, tf.hits, (float(p[0]), float(p[1])),
                                     (float(tr["p"][0]), float(tr["p"][1])), (float(tr["v"][0]), float(tr["v"][1])),
                                     (float(tf.x[0]), float(tf.x[1])), (float(tf.x[2]), float(tf.x[3])), nis))
        for tid in [k for k in filters if k not in seen]:
            del filters[tid]
    return out

