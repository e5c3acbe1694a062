"""Section III disparity selection: the FIS of eq. (10)-(12) scores every (segment, disparity),
winner-take-all keeps the best disparity per segment.

With ``nmi_candidates = K`` (0 < K < D) the firmware evaluates NMI only for the K disparities with
the highest FIS(NCC, IGSAD) — the FIS with Data Cost 2 replaced by IGSAD alone, ties to the
smaller d — and the WTA runs over those K; with K = 0 (or K >= D) it runs over every d.
WTA ties go to the smaller d.

With ``cost.subpixel``, a parabola through the scores at d-1, d, d+1 (when both neighbours took
part in the WTA) moves the winner to its vertex, d + (s(d+1) - s(d-1)) / (2 (2 s(d) - s(d-1) - s(d+1))),
by at most half a pixel.

The FIS is scikit-fuzzy's (:class:`fuzzyctl.fis.Fis`): ``engine="skfuzzy"`` runs
``ControlSystemSimulation`` on every distinct input pair; ``engine="fast"`` (default) runs the
vectorised twin of the same arithmetic, cross-checked against ``ControlSystemSimulation`` on a
sample of the winners' input pairs of every run (``pipeline.match``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fis import Fis
from .cost import SegmentCosts

ENGINES = ("fast", "skfuzzy")


@dataclass
class SegmentDecision:
    disparity: np.ndarray  # (n,) int, -1 = none
    disparity_sub: np.ndarray  # (n,) float px with the sub-pixel offset, NaN = none
    score: np.ndarray  # (n,) FIS output of the winner
    dc1: np.ndarray  # (n,) the winner's inputs
    dc2: np.ndarray
    candidates: np.ndarray  # (n, K) disparities that took part in the WTA


def fis_scores(fis: Fis, dc1: np.ndarray, dc2: np.ndarray, engine: str = "fast", check_samples: int = 0) -> np.ndarray:
    """FIS output for every pair (arrays of one shape); identical pairs are evaluated once.

    ``check_samples`` > 0 cross-checks the fast engine on that many of the pairs (FatalError on
    disagreement); the pipeline does it once per run on the winners instead.
    """
    shape = np.shape(dc1)
    pairs, inverse = np.unique(np.stack([np.ravel(dc1), np.ravel(dc2)], axis=1), axis=0, return_inverse=True)
    if engine == "skfuzzy":
        out = fis.evaluate_many(pairs[:, 0], pairs[:, 1])
    elif engine == "fast":
        out = fis.evaluate_fast(pairs[:, 0], pairs[:, 1])
        if check_samples:
            fis.cross_check(pairs[:, 0], pairs[:, 1], samples=check_samples)
    else:
        raise ValueError(f"unknown FIS engine {engine!r} (engines: {', '.join(ENGINES)})")
    return out[inverse.ravel()].reshape(shape)


def select_candidates(costs: SegmentCosts, fis: Fis, k: int, engine: str = "fast") -> np.ndarray:
    """(n, K) disparities: the K best by FIS(NCC, IGSAD), best first, ties -> smaller d."""
    n, D = costs.ncc.shape
    if k <= 0 or k >= D:
        return np.tile(np.arange(D), (n, 1))
    pre = fis_scores(fis, costs.ncc, costs.igsad, engine)
    order = np.argsort(-pre, axis=1, kind="stable")  # stable: equal scores keep ascending d
    return order[:, :k]


def fis_winner_take_all(
    costs: SegmentCosts, fis: Fis, alpha: float, nmi_candidates: int, engine: str = "fast", subpixel: bool = False
) -> SegmentDecision:
    """argmax over the candidates of FIS(DC1, DC2), eq. (8)-(12); ties -> smaller d."""
    cand = np.sort(select_candidates(costs, fis, nmi_candidates, engine), axis=1)  # ascending d
    rows = np.arange(cand.shape[0])[:, None]
    dc1 = costs.ncc[rows, cand]
    dc2 = costs.dc2(alpha)[rows, cand]
    score = fis_scores(fis, dc1, dc2, engine)
    best = np.argmax(score, axis=1)  # first maximum = smallest d among equal scores
    r = np.arange(cand.shape[0])
    winner = cand[r, best].astype(np.int64)
    n, D = costs.ncc.shape
    all_scores = np.full((n, D), np.nan)  # NaN = not a candidate
    all_scores[rows, cand] = score
    offset = subpixel_offset(all_scores, winner) if subpixel else np.zeros(n)
    return SegmentDecision(
        disparity=winner,
        disparity_sub=winner + offset,
        score=score[r, best],
        dc1=dc1[r, best],
        dc2=dc2[r, best],
        candidates=cand,
    )


def subpixel_offset(scores: np.ndarray, winner: np.ndarray) -> np.ndarray:
    """Parabola vertex offset [px] in [-1/2, 1/2] per segment; 0 where d-1 or d+1 was not scored
    (outside [0, D) or not a candidate) or the three scores are not strictly concave."""
    n, D = scores.shape
    r = np.arange(n)
    has = (winner > 0) & (winner < D - 1)
    s0 = scores[r, winner]
    sm = np.where(has, scores[r, np.clip(winner - 1, 0, D - 1)], np.nan)
    sp = np.where(has, scores[r, np.clip(winner + 1, 0, D - 1)], np.nan)
    curv = 2.0 * s0 - sm - sp  # > 0 at a strict maximum
    ok = ~np.isnan(curv) & (curv > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        off = np.where(ok, (sp - sm) / (2.0 * np.where(ok, curv, 1.0)), 0.0)
    return np.clip(off, -0.5, 0.5)


def paint_segments(labels: np.ndarray, seg_disp: np.ndarray) -> np.ndarray:
    """Per-pixel disparity map [px] (float64, NaN = invalid) from per-segment disparities."""
    d = np.asarray(seg_disp, dtype=np.float64)
    d = np.where(d < 0, np.nan, d)
    return d[labels]
