"""Scenario-by-scenario comparison of closed-loop suite results (``fuzzystereo sim suite --json``).

A planner or tracker change moves failures between scenarios: one run reaches a goal it missed,
another collides where it reached before. The totals alone hide that, and with a few failures in
a hundred runs a difference of one or two is within what a harmless change does. This module pairs
the scenarios of a baseline and a candidate run (same seed, same count), lists every scenario whose
outcome changed, and gives the exact two-sided sign test of the discordant pairs (reached in one
run only): the probability that a change with no effect moves at least that many scenarios one way.
The same test is given for contacts (a collision or a strike in one run only, solvable and blocked
scenarios alike), since the suite's safety target is about contacts, not arrivals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import FatalError, load_json

# Outcome classes of a solvable scenario, worst first (for "worse"/"better" of a changed pair).
_SOLVABLE_RANK = {"collision": 0, "struck": 1, "timeout": 2, "blocked_stop": 3, "no_progress_stop": 3, "error": 2,
                 "reached": 4}


@dataclass
class Outcome:
    key: str          # "12" (solvable) or "b3" (no free path)
    blocked: bool     # a scenario without a free path (success = safe stop)
    status: str
    success: bool
    time_s: float
    features: str
    contact: bool = False  # collided or struck


@dataclass
class SuiteSummary:
    path: str
    seed: int | None
    solvable: int = 0
    reached: int = 0
    collisions: int = 0
    struck: int = 0
    blocked: int = 0
    safe_stops: int = 0
    mean_time_reached_s: float | None = None


@dataclass
class PairDiff:
    base: SuiteSummary
    new: SuiteSummary
    changed: list[dict[str, Any]] = field(default_factory=list)
    gained: int = 0        # solvable: reached only in the new run
    lost: int = 0          # solvable: reached only in the base run
    safe_gained: int = 0   # blocked: safe stop only in the new run
    safe_lost: int = 0
    contacts_fewer: int = 0  # any scenario: a contact only in the base run
    contacts_more: int = 0   # any scenario: a contact only in the new run


def _load(path: Path) -> dict[str, Any]:
    data = load_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("scenarios"), list):
        raise FatalError(f"{path}: no 'scenarios' list (expected `fuzzystereo sim suite --json` output)")
    return data


def outcomes(path: Path) -> tuple[SuiteSummary, dict[str, Outcome]]:
    """The summary and the per-scenario outcomes of one suite JSON file."""
    data = _load(path)
    summ = SuiteSummary(path=str(path), seed=data.get("seed"))
    out: dict[str, Outcome] = {}
    times = []
    for i, s in enumerate(data["scenarios"]):
        if "index" not in s or not isinstance(s.get("status"), str):
            raise FatalError(f"{path}: scenarios[{i}] has no 'index' or no 'status'")
        blocked = bool(s.get("blocked", False))
        key = f"b{s['index']}" if blocked else str(s["index"])
        st = s["status"]
        success = bool(s.get("safe_stop")) if blocked else bool(s.get("reached", st == "reached"))
        t = float(s.get("time_s") or 0.0)
        collided = bool(s.get("collided", st == "collision"))
        struck = bool(s.get("struck", st == "struck"))
        out[key] = Outcome(key, blocked, st, success, t, str(s.get("features", "")).strip(), collided or struck)
        if blocked:
            summ.blocked += 1
            summ.safe_stops += success
        else:
            summ.solvable += 1
            summ.reached += success
            if success:
                times.append(t)
        summ.collisions += collided
        summ.struck += struck
    summ.mean_time_reached_s = sum(times) / len(times) if times else None
    return summ, out


def sign_test_p(gained: int, lost: int) -> float:
    """Exact two-sided sign test of `gained` against `lost` discordant pairs under p = 1/2."""
    n = gained + lost
    if n == 0:
        return 1.0
    k = min(gained, lost)
    tail = sum(math.comb(n, i) for i in range(k + 1)) / 2.0**n
    return min(1.0, 2.0 * tail)


def diff(base_path: Path, new_path: Path, time_change_s: float = math.inf) -> PairDiff:
    """Pairs the scenarios of two runs of the same suite. A scenario counts as changed when its
    outcome class differs, or (both reached) its time differs by more than time_change_s."""
    sb, ob = outcomes(base_path)
    sn, on = outcomes(new_path)
    if sb.seed is not None and sn.seed is not None and sb.seed != sn.seed:
        raise FatalError(f"{new_path}: seed {sn.seed} differs from {base_path}'s seed {sb.seed} "
                         "(compare runs of the same suite)")
    missing = sorted(set(ob) ^ set(on), key=_order)
    if missing:
        raise FatalError(f"{new_path}: scenarios {', '.join(missing[:8])} are in only one of the two files "
                         "(same --count and --only needed)")
    d = PairDiff(sb, sn)
    for key in sorted(ob, key=_order):
        a, b = ob[key], on[key]
        if a.success != b.success:
            if a.blocked:
                d.safe_gained += b.success
                d.safe_lost += a.success
            else:
                d.gained += b.success
                d.lost += a.success
        d.contacts_fewer += a.contact and not b.contact
        d.contacts_more += b.contact and not a.contact
        timed = a.success and b.success and abs(a.time_s - b.time_s) > time_change_s
        if a.status != b.status or timed:
            if a.blocked:
                direction = "better" if b.success and not a.success else ("worse" if a.success and not b.success else "other")
            else:
                ra, rb = _SOLVABLE_RANK.get(a.status, 2), _SOLVABLE_RANK.get(b.status, 2)
                direction = "better" if rb > ra else ("worse" if rb < ra else "time")
            d.changed.append({"scenario": key, "features": a.features, "base": a.status, "base_time_s": a.time_s,
                              "new": b.status, "new_time_s": b.time_s, "change": direction})
    return d


def _order(key: str) -> tuple[int, int]:
    return (1, int(key[1:])) if key.startswith("b") else (0, int(key))


def to_json(pairs: list[PairDiff]) -> dict[str, Any]:
    """JSON form: per pair the two summaries, the changed scenarios and the sign test; totals."""
    def summ(s: SuiteSummary) -> dict[str, Any]:
        return dict(s.__dict__)
    g = sum(p.gained for p in pairs)
    lo = sum(p.lost for p in pairs)
    cf = sum(p.contacts_fewer for p in pairs)
    cm = sum(p.contacts_more for p in pairs)
    return {
        "pairs": [{"base": summ(p.base), "new": summ(p.new), "changed": p.changed, "gained": p.gained,
                   "lost": p.lost, "safe_gained": p.safe_gained, "safe_lost": p.safe_lost,
                   "sign_test_p": sign_test_p(p.gained, p.lost),
                   "contacts_fewer": p.contacts_fewer, "contacts_more": p.contacts_more,
                   "contacts_sign_test_p": sign_test_p(p.contacts_fewer, p.contacts_more)} for p in pairs],
        "total": {
            "solvable": sum(p.base.solvable for p in pairs),
            "reached_base": sum(p.base.reached for p in pairs), "reached_new": sum(p.new.reached for p in pairs),
            "collisions_base": sum(p.base.collisions for p in pairs),
            "collisions_new": sum(p.new.collisions for p in pairs),
            "safe_stops_base": sum(p.base.safe_stops for p in pairs),
            "safe_stops_new": sum(p.new.safe_stops for p in pairs),
            "blocked": sum(p.base.blocked for p in pairs),
            "gained": g, "lost": lo, "sign_test_p": sign_test_p(g, lo),
            "contacts_base": sum(p.base.collisions + p.base.struck for p in pairs),
            "contacts_new": sum(p.new.collisions + p.new.struck for p in pairs),
            "contacts_fewer": cf, "contacts_more": cm, "contacts_sign_test_p": sign_test_p(cf, cm),
        },
    }
