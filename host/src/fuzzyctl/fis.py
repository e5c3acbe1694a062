"""The Mamdani fuzzy inference system of eq. (10)-(12) and Table I, built with scikit-fuzzy.

The definition is data: ``common/fis/fis.toml``, read by the firmware too. This module

* loads and validates it (:func:`load_definition`) — every fault is a :class:`FatalError` naming
  the file and the term, rule or parameter at fault;
* builds the scikit-fuzzy control system from it (:func:`build_control_system`): antecedents on
  ``np.linspace(0, 1, input_points)``, the consequent on ``np.linspace(0, 1, output_points)``,
  ``fuzz.trimf``/``fuzz.trapmf`` terms, one ``ctrl.Rule`` per Table I row (AND = min), max
  aggregation, centroid defuzzification;
* evaluates it (:class:`Fis`): ``evaluate(dc1, dc2)`` is one ``ControlSystemSimulation`` run —
  the oracle; ``evaluate_many`` runs the simulation on arrays, and ``evaluate_fast`` is a NumPy
  twin of exactly what scikit-fuzzy computes (same upsampled output universe, same piecewise-linear
  centroid), vectorised over many input pairs, for the desktop reference (hundreds of thousands of
  evaluations per image pair, where one simulation run costs ~3 ms). The twin is checked against
  the simulation by the tests (``tests/python/test_fis.py``) and by every reference run on a
  sample of its inputs (:meth:`Fis.cross_check`).
"""

from __future__ import annotations

import tomllib
import warnings
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Iterable

import numpy as np

from . import paths
from .errors import FatalError

#: Membership function kinds and their parameter count (scikit-fuzzy semantics).
MF_PARAM_COUNT = {"trimf": 3, "trapmf": 4}
#: The two antecedents, in the order of Table I's columns.
INPUT_NAMES = ("dc1", "dc2")


# ---- definition -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Term:
    name: str
    mf: str  # "trimf" | "trapmf"
    params: tuple[float, ...]

    def membership(self, universe: np.ndarray) -> np.ndarray:
        """The term's membership sampled on ``universe`` (``fuzz.trimf`` / ``fuzz.trapmf``)."""
        import skfuzzy as fuzz

        fn = fuzz.trimf if self.mf == "trimf" else fuzz.trapmf
        return fn(np.asarray(universe, dtype=np.float64), list(self.params))


@dataclass(frozen=True)
class Variable:
    name: str
    label: str
    terms: tuple[Term, ...]

    def term_names(self) -> list[str]:
        return [t.name for t in self.terms]

    def index(self, name: str) -> int:
        return self.term_names().index(name)


@dataclass(frozen=True)
class Rule:
    number: int
    dc1: str
    dc2: str
    out: str


@dataclass(frozen=True)
class FisDefinition:
    name: str
    version: int
    input_points: int
    output_points: int
    dc1: Variable
    dc2: Variable
    output: Variable
    rules: tuple[Rule, ...]
    source: str = field(default="<string>", compare=False)

    @property
    def input_universe(self) -> np.ndarray:
        return np.linspace(0.0, 1.0, self.input_points)

    @property
    def output_universe(self) -> np.ndarray:
        return np.linspace(0.0, 1.0, self.output_points)

    def rule(self, number: int) -> Rule:
        for r in self.rules:
            if r.number == number:
                return r
        raise KeyError(number)


def load_definition(path: str | Path | None = None) -> FisDefinition:
    """Parse and validate a FIS TOML file (default: ``common/fis/fis.toml``)."""
    path = Path(path) if path is not None else paths.fis_file()
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise FatalError(f"cannot read FIS definition {path}: {exc.strerror}") from exc
    return parse_definition(text, str(path))


def parse_definition(text: str, source: str = "<string>") -> FisDefinition:
    """Parse and validate FIS TOML text; every fault is a FatalError starting with ``source``."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FatalError(f"{source}: not valid TOML: {exc}") from exc

    def fail(msg: str) -> FatalError:
        return FatalError(f"{source}: {msg}")

    name = doc.get("name", "unnamed")
    version = doc.get("version", 1)
    if not isinstance(name, str):
        raise fail("'name' must be a string")
    if not isinstance(version, int) or isinstance(version, bool):
        raise fail("'version' must be an integer")

    universe = doc.get("universe", {})
    points = {}
    for key, default in (("input_points", 1001), ("output_points", 1401)):
        value = universe.get(key, default)
        if not isinstance(value, int) or isinstance(value, bool) or not 2 <= value <= 100_000:
            raise fail(f"universe.{key} = {value!r} must be an integer in [2, 100000]")
        points[key] = value

    inputs = doc.get("inputs")
    if not isinstance(inputs, dict):
        raise fail("missing table [inputs.dc1] / [inputs.dc2]")
    unknown = sorted(set(inputs) - set(INPUT_NAMES))
    if unknown:
        raise fail(f"unknown input(s) {', '.join(unknown)}; the FIS has exactly dc1 and dc2")
    variables = {}
    for var_name in INPUT_NAMES:
        if var_name not in inputs:
            raise fail(f"missing table [inputs.{var_name}]")
        variables[var_name] = _parse_variable(inputs[var_name], f"inputs.{var_name}", var_name, fail)
    output_table = doc.get("output")
    if not isinstance(output_table, dict):
        raise fail("missing table [output]")
    output = _parse_variable(output_table, "output", output_table.get("name", "score"), fail)

    # Table I. In fis.toml the `rules = [...]` array follows the [output] table, so TOML puts it
    # at output.rules; a top-level `rules` (written before any table) is accepted too.
    if "rules" in doc and "rules" in output_table:
        raise fail("rules are given twice (top level and in [output])")
    raw_rules = doc.get("rules", output_table.get("rules"))
    if not isinstance(raw_rules, list) or not raw_rules:
        raise fail("missing rules: expected rules = [[number, dc1 term, dc2 term, output term], ...]")
    rules = _parse_rules(raw_rules, variables["dc1"], variables["dc2"], output, fail)

    return FisDefinition(
        name=name,
        version=version,
        input_points=points["input_points"],
        output_points=points["output_points"],
        dc1=variables["dc1"],
        dc2=variables["dc2"],
        output=output,
        rules=tuple(rules),
        source=source,
    )


def _parse_variable(table: dict, where: str, var_name: str, fail) -> Variable:
    raw_terms = table.get("terms")
    if not isinstance(raw_terms, list) or not raw_terms:
        raise fail(f"{where}.terms must be a non-empty array of {{ name, mf, params }}")
    terms: list[Term] = []
    seen: set[str] = set()
    for i, raw in enumerate(raw_terms):
        here = f"{where}.terms[{i}]"
        if not isinstance(raw, dict):
            raise fail(f"{here} must be a table {{ name, mf, params }}")
        extra = sorted(set(raw) - {"name", "mf", "params"})
        if extra:
            raise fail(f"{here}: unknown key(s) {', '.join(extra)}")
        name = raw.get("name")
        if not isinstance(name, str) or not name:
            raise fail(f"{here}: 'name' must be a non-empty string")
        here = f"{where} term '{name}'"
        if name in seen:
            raise fail(f"{here} is defined twice")
        seen.add(name)
        mf = raw.get("mf")
        if mf not in MF_PARAM_COUNT:
            raise fail(f"{here}: mf = {mf!r}, expected one of {', '.join(MF_PARAM_COUNT)}")
        params = raw.get("params")
        n = MF_PARAM_COUNT[mf]
        if (
            not isinstance(params, list)
            or len(params) != n
            or not all(isinstance(p, (int, float)) and not isinstance(p, bool) for p in params)
        ):
            raise fail(f"{here}: {mf} needs params = [{n} numbers], got {params!r}")
        p = tuple(float(v) for v in params)
        if not all(np.isfinite(p)):
            raise fail(f"{here}: params {list(p)} must be finite")
        if any(b < a for a, b in zip(p, p[1:])):
            raise fail(f"{here}: params {list(p)} must be non-decreasing")
        if p[-1] <= p[0]:
            raise fail(f"{here}: params {list(p)} describe an empty support (first == last)")
        if p[0] > 1.0 or p[-1] < 0.0:
            raise fail(f"{here}: params {list(p)} do not overlap the universe [0, 1]")
        terms.append(Term(name, mf, p))
    label = table.get("label", var_name)
    return Variable(str(var_name), str(label), tuple(terms))


def _parse_rules(raw_rules: list, dc1: Variable, dc2: Variable, out: Variable, fail) -> list[Rule]:
    rules: list[Rule] = []
    numbers: dict[int, int] = {}
    pairs: dict[tuple[str, str], int] = {}
    for i, raw in enumerate(raw_rules):
        if (
            not isinstance(raw, list)
            or len(raw) != 4
            or not isinstance(raw[0], int)
            or isinstance(raw[0], bool)
            or not all(isinstance(v, str) for v in raw[1:])
        ):
            raise fail(f"rules[{i}] = {raw!r}: expected [number, dc1 term, dc2 term, output term]")
        number, t1, t2, to = raw
        for var, term in ((dc1, t1), (dc2, t2), (out, to)):
            if term not in var.term_names():
                raise fail(
                    f"rule {number}: unknown {var.name} term '{term}' "
                    f"(terms: {', '.join(var.term_names())})"
                )
        if number in numbers:
            raise fail(f"rule number {number} is used twice (rules[{numbers[number]}] and rules[{i}])")
        numbers[number] = i
        if (t1, t2) in pairs:
            raise fail(
                f"rule {number}: ({t1}, {t2}) already has a consequent in rule {pairs[(t1, t2)]}"
            )
        pairs[(t1, t2)] = number
        rules.append(Rule(number, t1, t2, to))
    return rules


# ---- scikit-fuzzy control system -------------------------------------------------------------


def build_control_system(defn: FisDefinition):
    """``(ControlSystem, dc1 Antecedent, dc2 Antecedent, Consequent)`` for the definition."""
    import skfuzzy.control as ctrl

    ant = {}
    for var in (defn.dc1, defn.dc2):
        a = ctrl.Antecedent(defn.input_universe, var.name)
        for term in var.terms:
            a[term.name] = term.membership(a.universe)
        ant[var.name] = a
    cons = ctrl.Consequent(defn.output_universe, defn.output.name, defuzzify_method="centroid")
    for term in defn.output.terms:
        cons[term.name] = term.membership(cons.universe)
    rules = [
        ctrl.Rule(ant["dc1"][r.dc1] & ant["dc2"][r.dc2], cons[r.out], label=f"rule{r.number}")
        for r in defn.rules
    ]
    return ctrl.ControlSystem(rules), ant["dc1"], ant["dc2"], cons


class Fis:
    """A FIS definition with its scikit-fuzzy control system and a vectorised twin."""

    #: array inputs per ControlSystemSimulation run (bounded memory, progress granularity)
    CHUNK = 2048

    def __init__(self, defn: FisDefinition):
        self.defn = defn
        self._twin = _MamdaniTwin(defn)
        self._memo: dict[tuple[float, float], float] = {}

    @cached_property
    def _control(self):
        # built on first use: constructing the networkx rule graph takes seconds
        return build_control_system(self.defn)

    @property
    def system(self):
        """The ``skfuzzy.control.ControlSystem``."""
        return self._control[0]

    @property
    def dc1_var(self):
        return self._control[1]

    @property
    def dc2_var(self):
        return self._control[2]

    @property
    def out_var(self):
        return self._control[3]

    # -- the oracle: scikit-fuzzy's ControlSystemSimulation --

    def evaluate(self, dc1: float, dc2: float) -> float:
        """One ``ControlSystemSimulation`` run: the FIS output for crisp inputs in [0, 1]."""
        key = (float(dc1), float(dc2))
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        value = float(self._simulate(np.array([key[0]]), np.array([key[1]]))[0])
        self._memo[key] = value
        return value

    def evaluate_many(self, dc1: Iterable[float], dc2: Iterable[float]) -> np.ndarray:
        """ControlSystemSimulation on arrays (identical pairs are evaluated once)."""
        a = np.asarray(dc1, dtype=np.float64).ravel()
        b = np.asarray(dc2, dtype=np.float64).ravel()
        if a.shape != b.shape:
            raise ValueError("dc1 and dc2 must have the same number of values")
        if a.size == 0:
            return np.zeros(0)
        pairs, inverse = np.unique(np.stack([a, b], axis=1), axis=0, return_inverse=True)
        out = np.empty(len(pairs))
        for lo in range(0, len(pairs), self.CHUNK):
            hi = min(lo + self.CHUNK, len(pairs))
            out[lo:hi] = self._simulate(pairs[lo:hi, 0], pairs[lo:hi, 1])
        return out[inverse.ravel()]

    def _simulate(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        import skfuzzy.control as ctrl

        # A fresh simulation per call: array inputs of a new shape would otherwise warn.
        sim = ctrl.ControlSystemSimulation(self.system, clip_to_bounds=True, cache=False)
        if a.size == 1:
            sim.input[self.dc1_var.label] = float(a[0])
            sim.input[self.dc2_var.label] = float(b[0])
        else:
            sim.input[self.dc1_var.label] = a
            sim.input[self.dc2_var.label] = b
        with warnings.catch_warnings():
            # scikit-fuzzy 0.5 calls np.maximum(a, b, out) positionally (deprecated in NumPy 2.4)
            warnings.filterwarnings("ignore", "Passing more than 2 positional", DeprecationWarning)
            sim.compute()
        return np.atleast_1d(np.asarray(sim.output[self.out_var.label], dtype=np.float64))

    # -- the twin: same arithmetic, vectorised --

    def evaluate_fast(self, dc1, dc2) -> np.ndarray:
        """Vectorised twin of :meth:`evaluate_many` (agrees to ~1e-12, see cross_check)."""
        a = np.asarray(dc1, dtype=np.float64)
        b = np.asarray(dc2, dtype=np.float64)
        shape = np.broadcast_shapes(a.shape, b.shape)
        a = np.broadcast_to(a, shape).ravel()
        b = np.broadcast_to(b, shape).ravel()
        out = np.empty(a.size)
        for lo in range(0, a.size, self._twin.CHUNK):
            hi = min(lo + self._twin.CHUNK, a.size)
            out[lo:hi] = self._twin(a[lo:hi], b[lo:hi])
        return out.reshape(shape)

    def cross_check(self, dc1, dc2, samples: int = 64, seed: int = 0, tol: float = 1e-9) -> float:
        """Max |twin - ControlSystemSimulation| over ``samples`` of the given pairs (FatalError > tol)."""
        a = np.asarray(dc1, dtype=np.float64).ravel()
        b = np.asarray(dc2, dtype=np.float64).ravel()
        if a.size == 0:
            return 0.0
        idx = np.random.default_rng(seed).choice(a.size, size=min(samples, a.size), replace=False)
        err = float(np.max(np.abs(self.evaluate_fast(a[idx], b[idx]) - self.evaluate_many(a[idx], b[idx]))))
        if not err <= tol:
            raise FatalError(
                f"vectorised FIS disagrees with scikit-fuzzy by {err:.3g} (> {tol:g}); "
                "this scikit-fuzzy version computes differently: re-run with --fis-engine skfuzzy"
            )
        return err


class _MamdaniTwin:
    """What ``ControlSystemSimulation.compute()`` does for this FIS, for a batch of input pairs.

    Per pair (skfuzzy 0.4/0.5, controlsystem.py):
      1. fuzzify: mu = np.interp(x, input universe, sampled term mf), inputs clipped to [0, 1];
      2. rules: firing = fmin(mu_dc1[term], mu_dc2[term]); cut[out term] = fmax over its rules;
      3. upsample the output universe with, per term, the points where its sampled mf crosses its
         cut (``_interp_universe_fast``: crossings of mf >= cut, or mf > 0 for a zero cut);
      4. aggregate: out(x) = max_term min(cut, np.interp(x, universe, mf)) on the upsampled points;
      5. centroid of the piecewise-linear out(x) (``skfuzzy.defuzzify.centroid``).
    Each term mf is unimodal (trimf/trapmf), so the set {mf >= cut} is one run of samples and its
    ends are found with searchsorted on the rising and falling halves.
    """

    CHUNK = 4096

    def __init__(self, defn: FisDefinition):
        self.u_in = defn.input_universe
        self.u_out = defn.output_universe
        self.mf1 = np.array([t.membership(self.u_in) for t in defn.dc1.terms])
        self.mf2 = np.array([t.membership(self.u_in) for t in defn.dc2.terms])
        self.rule_idx = np.array(
            [(defn.dc1.index(r.dc1), defn.dc2.index(r.dc2), defn.output.index(r.out)) for r in defn.rules]
        )
        used = sorted(set(self.rule_idx[:, 2].tolist()))  # terms never fired are skipped by skfuzzy
        self.out_terms = np.array(used)
        self.mf_out = np.array([defn.output.terms[k].membership(self.u_out) for k in used])
        self.peak = np.argmax(self.mf_out, axis=1)
        for k, m in enumerate(self.mf_out):
            p = self.peak[k]
            if np.any(np.diff(m[: p + 1]) < 0) or np.any(np.diff(m[p:]) > 0):
                raise FatalError(f"output term {defn.output.terms[used[k]].name} is not unimodal")
        nz = [np.flatnonzero(m > 0) for m in self.mf_out]
        self.support = [(int(i[0]), int(i[-1]) + 1) if i.size else (0, 0) for i in nz]
        # Interval weights: sum_j moment_j*area_j and sum_j area_j over the plain universe are
        # linear in the samples y (see _trapezoid).
        x = self.u_out
        dx = np.diff(x)
        self.w_moment = np.zeros(x.size)
        self.w_moment[:-1] += dx * dx / 6.0 + 0.5 * x[:-1] * dx
        self.w_moment[1:] += dx * dx / 3.0 + 0.5 * x[:-1] * dx
        self.w_area = np.zeros(x.size)
        self.w_area[:-1] += 0.5 * dx
        self.w_area[1:] += 0.5 * dx

    def _cuts(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        mu1 = np.array([np.interp(a, self.u_in, m) for m in self.mf1])  # (T1, N)
        mu2 = np.array([np.interp(b, self.u_in, m) for m in self.mf2])
        fire = np.fmin(mu1[self.rule_idx[:, 0]], mu2[self.rule_idx[:, 1]])  # (R, N)
        cuts = np.zeros((len(self.out_terms), a.size))
        for row, k in enumerate(self.out_terms):
            cuts[row] = np.max(fire[self.rule_idx[:, 2] == k], axis=0)
        return cuts  # (K, N)

    def _crossings(self, k: int, c: np.ndarray) -> np.ndarray:
        """(N, 2) universe points where term k's sampled mf crosses cut c (NaN = none)."""
        x, m, p = self.u_out, self.mf_out[k], self.peak[k]
        last = len(m) - 1
        rising, falling = m[: p + 1], m[p:]
        zero = c == 0.0
        # first sample index with mf >= c (mf > 0 for a zero cut) on the rising half
        lo = np.where(zero, np.searchsorted(rising, 0.0, side="right"), np.searchsorted(rising, c, side="left"))
        # number of leading samples with mf >= c (> 0) on the falling half
        nf = np.where(zero, np.searchsorted(-falling, 0.0, side="left"), np.searchsorted(-falling, -c, side="right"))
        hi = p + nf - 1
        nonempty = lo <= p
        out = np.full((c.size, 2), np.nan)
        for col, idx, ok in ((0, lo - 1, nonempty & (lo > 0)), (1, hi, nonempty & (hi < last) & (nf > 0))):
            i = np.clip(idx, 0, last - 1)
            xx = x[i] + (c - m[i]) * (x[i + 1] - x[i]) / np.where(ok, m[i + 1] - m[i], 1.0)
            out[:, col] = np.where(ok, xx, np.nan)
        return out

    def __call__(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        a = np.clip(a, self.u_in[0], self.u_in[-1])
        b = np.clip(b, self.u_in[0], self.u_in[-1])
        cuts = self._cuts(a, b)  # (K, N)
        n = a.size
        # Aggregated output mf on the universe samples (each term only over its support).
        y_grid = np.zeros((n, self.u_out.size))
        for k, (s0, s1) in enumerate(self.support):
            np.maximum(y_grid[:, s0:s1], np.minimum(cuts[k][:, None], self.mf_out[k][None, s0:s1]),
                       out=y_grid[:, s0:s1])
        # ... and on the extra points of step 3, sorted per row (NaN = no point, sorts last).
        extra = np.concatenate([self._crossings(k, cuts[k]) for k in range(len(cuts))], axis=1)
        extra.sort(axis=1)
        valid = ~np.isnan(extra)
        e = np.where(valid, extra, self.u_out[-1])
        y_extra = np.zeros(e.shape)
        for k in range(len(cuts)):
            mk = np.interp(e, self.u_out, self.mf_out[k])
            np.maximum(y_extra, np.minimum(cuts[k][:, None], mk), out=y_extra)
        # Centroid over the merged points = sums over the plain universe intervals (linear in y)
        # corrected in the intervals that the extra points split.
        moment = y_grid @ self.w_moment
        area = y_grid @ self.w_area
        x, y = self.u_out, y_grid
        rows = np.arange(n)[:, None]
        j = np.clip(np.searchsorted(x, e, side="right") - 1, 0, x.size - 2)  # interval of each point
        xj, xj1 = x[j], x[j + 1]
        yj, yj1 = y[rows, j], y[rows, j + 1]
        same_prev = np.zeros_like(valid)
        same_prev[:, 1:] = valid[:, 1:] & valid[:, :-1] & (j[:, 1:] == j[:, :-1])
        same_next = np.zeros_like(valid)
        same_next[:, :-1] = same_prev[:, 1:]
        prev_x = np.where(same_prev, np.roll(e, 1, axis=1), xj)
        prev_y = np.where(same_prev, np.roll(y_extra, 1, axis=1), yj)
        first = valid & ~same_prev
        last = valid & ~same_next
        for (xa, ya, xb, yb), sign, mask in (
            ((prev_x, prev_y, e, y_extra), 1.0, valid),  # piece ending at each extra point
            ((e, y_extra, xj1, yj1), 1.0, last),  # piece from the interval's last extra point
            ((xj, yj, xj1, yj1), -1.0, first),  # the interval they replace
        ):
            m_piece, a_piece = _trapezoid(xa, ya, xb, yb)
            moment += sign * np.where(mask, m_piece, 0.0).sum(axis=1)
            area += sign * np.where(mask, a_piece, 0.0).sum(axis=1)
        return moment / np.where(area > 0, area, 1.0)


def _trapezoid(x1, y1, x2, y2):
    """(moment * area, area) of the trapezoid under the segment (x1, y1)-(x2, y2).

    ``skfuzzy.defuzzify.centroid`` splits into rectangle/triangle/trapezoid cases; all are this
    formula: area = dx (y1 + y2) / 2, centroid = x1 + dx (y2 + y1/2) * 2/3 / (y1 + y2).
    """
    dx = x2 - x1
    return dx * (dx * (y2 + 0.5 * y1) / 3.0 + 0.5 * x1 * (y1 + y2)), 0.5 * dx * (y1 + y2)


@lru_cache(maxsize=4)
def _default_fis(path: str | None) -> Fis:
    return Fis(load_definition(path))


def get_fis(path: str | Path | None = None) -> Fis:
    """The (cached) FIS for a definition file, default ``common/fis/fis.toml``."""
    return _default_fis(str(path) if path is not None else None)


def evaluate(dc1: float, dc2: float) -> float:
    """FIS output of the shared definition for one pair (one ControlSystemSimulation run)."""
    return get_fis().evaluate(dc1, dc2)
