"""Section III disparity selection: the FIS of eq. (10)-(12) scores every (segment, disparity),
winner-take-all keeps the best disparity per segment.

With ``nmi_candidates = K`` (0 < K < D) the firmware evaluates NMI only for the K disparities with
the highest FIS(NCC, IGSAD) — the FIS with Data Cost 2 replaced by IGSAD alone — and the WTA runs
over those K; with K = 0 (or K >= D) it runs over every d. WTA ties go to the smaller d.

The candidate ranking key is the firmware's ``FisLut::lookup_nearest``: the FIS read at the
NEAREST node of the N x N lookup table (N = ``fis.lut_size``), no interpolation. From the Q16
inputs a, b the node is ``ia = (min(a, 65536) (N-1) + 32768) >> 16`` (likewise ib) and its value
is FIS(ia/(N-1), ib/(N-1)) rounded to Q16; ties go to the smaller d. The reference forms the same
Q16 inputs (NCC rounded to nearest; IGSAD as ``65536 - trunc(GSAD_d * (65536 / max GSAD))``, the
firmware's expression on the same exact integer GSAD) and evaluates the exact FIS (not a table) at
the node coordinates, so the ranking differs from the firmware's only where a node value lies
within float rounding of a Q16 half-step.

With ``cost.subpixel``, a parabola through the scores at d-1, d, d+1 moves the winner to its
vertex, d + (s(d+1) - s(d-1)) / (2 (2 s(d) - s(d-1) - s(d+1))), by at most half a pixel. The scores
are the candidates' own when both neighbours took part in the WTA; otherwise, with
``cost.subpixel_every_segment``, all three are FIS(NCC(d'), alpha NMI(winner) + (1 - alpha)
IGSAD(d')) — the winner's NMI stands in for the one the firmware did not compute (docs/algorithm.md 4).

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
    candidate_scores: np.ndarray | None = None  # (n, K) their FIS scores (the candidate retry, docs/algorithm.md 5b)


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


Q16_ONE = 1 << 16  # the firmware's kQ16One: 1.0 in Q16


def q16_inputs(costs: SegmentCosts) -> tuple[np.ndarray, np.ndarray]:
    """(NCC, IGSAD) as the firmware holds them, Q16 integers (int64) in [0, 65536].

    NCC: ``round(ncc * 65536)`` of the clamped value (segment_costs.cpp ``ncc_q16``). IGSAD:
    ``65536 - trunc(GSAD_d * (65536 / max_d GSAD))`` in double, as ``igsad_q16`` computes it, from
    the exact integer GSAD when the costs carry it (else the float IGSAD rounded to nearest).
    """
    ncc = np.minimum(np.floor(np.clip(costs.ncc, 0.0, 1.0) * Q16_ONE + 0.5), Q16_ONE).astype(np.int64)
    if costs.gsad is not None:
        gmax = costs.gsad.max(axis=1, keepdims=True)
        inv = np.where(gmax > 0, float(Q16_ONE) / np.where(gmax > 0, gmax, 1.0), 0.0)
        igsad = (Q16_ONE - np.trunc(costs.gsad * inv)).astype(np.int64)
    else:
        igsad = np.floor(np.clip(costs.igsad, 0.0, 1.0) * Q16_ONE + 0.5).astype(np.int64)
    return ncc, igsad


def nearest_node(q16: np.ndarray, lut_size: int) -> np.ndarray:
    """Index of the nearest lookup-table node of a Q16 input (``FisLut::lookup_nearest``)."""
    n1 = lut_size - 1
    return (np.minimum(np.asarray(q16, dtype=np.int64), Q16_ONE) * n1 + (Q16_ONE >> 1)) >> 16


def nearest_node_scores(costs: SegmentCosts, fis: Fis, lut_size: int, engine: str = "fast") -> np.ndarray:
    """(n, D) Q16 ranking keys: the exact FIS at the nearest table node of (NCC, IGSAD), rounded."""
    a, b = q16_inputs(costs)
    n1 = float(lut_size - 1)
    value = fis_scores(fis, nearest_node(a, lut_size) / n1, nearest_node(b, lut_size) / n1, engine)
    return np.floor(np.clip(value, 0.0, 1.0) * Q16_ONE + 0.5).astype(np.int64)


def select_candidates(costs: SegmentCosts, fis: Fis, k: int, engine: str = "fast", lut_size: int = 257) -> np.ndarray:
    """(n, K) disparities: the K best by the nearest-node FIS(NCC, IGSAD) (module doc), best first,
    ties -> smaller d."""
    n, D = costs.ncc.shape
    if k <= 0 or k >= D:
        return np.tile(np.arange(D), (n, 1))
    pre = nearest_node_scores(costs, fis, lut_size, engine)
    order = np.argsort(-pre, axis=1, kind="stable")  # stable: equal scores keep ascending d
    return order[:, :k]


def fis_winner_take_all(
    costs: SegmentCosts,
    fis: Fis,
    alpha: float,
    nmi_candidates: int,
    engine: str = "fast",
    subpixel: bool = False,
    lut_size: int = 257,
    subpixel_every_segment: bool = False,
) -> SegmentDecision:
    """argmax over the candidates of FIS(DC1, DC2), eq. (8)-(12); ties -> smaller d."""
    cand = np.sort(select_candidates(costs, fis, nmi_candidates, engine, lut_size), axis=1)  # ascending d
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
    if subpixel and subpixel_every_segment:
        all_scores = _fill_missing_neighbours(all_scores, winner, costs, fis, alpha, engine)
    offset = subpixel_offset(all_scores, winner) if subpixel else np.zeros(n)
    return SegmentDecision(
        disparity=winner,
        disparity_sub=winner + offset,
        score=score[r, best],
        dc1=dc1[r, best],
        dc2=dc2[r, best],
        candidates=cand,
        candidate_scores=score,
    )


def _fill_missing_neighbours(
    scores: np.ndarray, winner: np.ndarray, costs: SegmentCosts, fis: Fis, alpha: float, engine: str
) -> np.ndarray:
    """Scores with d-1, d, d+1 of every interior winner whose two neighbours were not both
    candidates replaced by FIS(NCC(d'), alpha NMI(winner) + (1 - alpha) IGSAD(d'))."""
    n, D = scores.shape
    r = np.arange(n)
    inner = (winner > 0) & (winner < D - 1)
    wm, wp = np.clip(winner - 1, 0, D - 1), np.clip(winner + 1, 0, D - 1)
    need = inner & (np.isnan(scores[r, wm]) | np.isnan(scores[r, wp]))
    if not need.any():
        return scores
    out = scores.copy()
    s, w = r[need], winner[need]
    cols = np.stack([w - 1, w, w + 1], axis=1)
    nmi_w = costs.nmi[s, w][:, None]
    dc2 = alpha * nmi_w + (1.0 - alpha) * costs.igsad[s[:, None], cols]
    out[s[:, None], cols] = fis_scores(fis, costs.ncc[s[:, None], cols], dc2, engine)
    return out


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
