"""The float64 desktop reference of the fuzzystereo matcher — the oracle for the firmware.

One module per stage, as in firmware/core/src/:
  image         eq. (5)      grey conversion, Sobel gradient magnitude
  segmentation               SLIC superpixels (float), label agreement
  cost          eq. (1)-(9)  NCC, NMI, gradient SAD per segment and disparity
  wta           eq. (10)-(12) FIS (scikit-fuzzy) + winner-take-all, NMI candidates
  lrcheck       eq. (13)     left-right consistency
  esr           eq. (14)-(15) entropy-based selective refinement
  pipeline                   chains them, one line per stage
"""

from .pipeline import STAGES, ReferenceResult, match

__all__ = ["STAGES", "ReferenceResult", "match"]
