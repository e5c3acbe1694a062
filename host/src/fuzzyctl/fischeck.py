"""``fuzzyctl fis check``: the firmware's FIS (LUT and double Mamdani) against scikit-fuzzy.

The acceptance criterion of the FIS issue: on >= 1000 random input pairs (fixed seed) plus the
corners, edges and term centres of [0, 1]^2, the firmware's LUT output is within 1 % of the output
range of scikit-fuzzy's ``ControlSystemSimulation``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import firmware
from .fis import Fis, load_definition

#: LUT tolerance: 1 % of the output range [0, 1].
LUT_TOLERANCE = 0.01
#: The firmware's double-precision Mamdani evaluation follows scikit-fuzzy's algorithm step by
#: step; only summation order and rounding differ.
EXACT_TOLERANCE = 1e-6


def check_points(n_random: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``n_random`` uniform pairs (seeded) + corners, edges (step 0.05) and the 6x6 term centres."""
    rng = np.random.default_rng(seed)
    pts = [rng.random((n_random, 2))]
    t = np.linspace(0.0, 1.0, 21)
    zeros, ones = np.zeros_like(t), np.ones_like(t)
    pts += [np.stack(c, axis=1) for c in ((t, zeros), (t, ones), (zeros, t), (ones, t))]
    centres = np.linspace(0.0, 1.0, 6)
    ca, cb = np.meshgrid(centres, centres, indexing="ij")
    pts.append(np.stack([ca.ravel(), cb.ravel()], axis=1))
    allp = np.unique(np.concatenate(pts), axis=0)
    return allp[:, 0], allp[:, 1]


@dataclass
class FisCheckResult:
    dc1: np.ndarray
    dc2: np.ndarray
    reference: np.ndarray  # scikit-fuzzy ControlSystemSimulation
    lut: np.ndarray  # firmware fixed-point LUT
    exact: np.ndarray  # firmware double Mamdani

    @property
    def lut_error(self) -> np.ndarray:
        return np.abs(self.lut - self.reference)

    @property
    def exact_error(self) -> np.ndarray:
        return np.abs(self.exact - self.reference)

    def worst(self, err: np.ndarray) -> tuple[float, float, float]:
        i = int(np.argmax(err))
        return float(err[i]), float(self.dc1[i]), float(self.dc2[i])

    def passed(self, lut_tol: float = LUT_TOLERANCE) -> bool:
        return bool(self.lut_error.max() <= lut_tol)


def check_firmware_fis(
    binary: str | Path,
    n_random: int = 1000,
    seed: int = 0,
    fis_path: str | Path | None = None,
    config_path: str | Path | None = None,
) -> FisCheckResult:
    """Run ``fuzzystereo fis eval`` on the check points and evaluate them with scikit-fuzzy."""
    dc1, dc2 = check_points(n_random, seed)
    lut, exact = firmware.fis_eval(binary, dc1, dc2, fis=fis_path, config=config_path)
    reference = Fis(load_definition(fis_path)).evaluate_many(dc1, dc2)
    return FisCheckResult(dc1, dc2, reference, lut, exact)
