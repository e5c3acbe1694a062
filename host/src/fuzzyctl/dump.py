"""The stage dump of docs/formats.md: read (firmware or reference) and write (reference).

A dump is a directory with ``meta.json``, ``left.png``/``right.png`` (8-bit grey, exactly as
matched) and one ``.npy`` per stage output. Fixed-point formats, as in the firmware:

* disparities: int16 Q4 (``value / 16`` px), :data:`INVALID_DISP` = -1 marks "no estimate";
* scores and data costs: int32 Q16 (``value / 65536`` in [0, 1]).

Conversions from float64 round to nearest, halves up (``floor(x * scale + 0.5)``), like the
firmware's integer rounding.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .errors import FatalError

FORMAT = "fuzzystereo-dump"
VERSION = 1
DISP_SHIFT = 4
DISP_SCALE = 1 << DISP_SHIFT  # Q4
Q16_ONE = 1 << 16
INVALID_DISP = -1

#: file -> (dtype, shape kind): "hw" = (H, W), "seg" = (n, SEG_COLUMNS)
ARRAYS: dict[str, tuple[np.dtype, str]] = {
    "labels_left": (np.dtype(np.int32), "hw"),
    "labels_right": (np.dtype(np.int32), "hw"),
    "seg_left": (np.dtype(np.int32), "seg"),
    "seg_right": (np.dtype(np.int32), "seg"),
    "disp_left_wta": (np.dtype(np.int16), "hw"),
    "disp_right_wta": (np.dtype(np.int16), "hw"),
    "lr_mask": (np.dtype(np.uint8), "hw"),
    "disp_lr": (np.dtype(np.int16), "hw"),
    "esr_replaced": (np.dtype(np.uint8), "hw"),
    "disp_esr": (np.dtype(np.int16), "hw"),
    "densify_changed": (np.dtype(np.uint8), "hw"),
    "disp_final": (np.dtype(np.int16), "hw"),
}
#: arrays that dumps written before the densify stage lack (disp_final is then the ESR map)
OPTIONAL = frozenset({"disp_esr", "densify_changed"})
#: columns of seg_*.npy: integer winner [px] (-1 = none), FIS score Q16, Data Cost 1 Q16,
#: Data Cost 2 Q16, painted disparity Q4 after the sub-pixel parabola (-1 = none)
SEG_DISP, SEG_SCORE, SEG_DC1, SEG_DC2, SEG_DISP_Q4 = range(5)
SEG_COLUMNS = 5


# ---- fixed-point conversions ------------------------------------------------------------------


def disp_to_q4(disp: np.ndarray) -> np.ndarray:
    """float [px] (NaN = invalid) -> int16 Q4 (-1 = invalid)."""
    d = np.asarray(disp, dtype=np.float64)
    q = np.floor(np.where(np.isnan(d), 0.0, d) * DISP_SCALE + 0.5)
    return np.where(np.isnan(d), INVALID_DISP, q).astype(np.int16)


def q4_to_disp(q4: np.ndarray) -> np.ndarray:
    """int16 Q4 (-1 = invalid) -> float [px] (NaN = invalid)."""
    q = np.asarray(q4)
    return np.where(q == INVALID_DISP, np.nan, q.astype(np.float64) / DISP_SCALE)


def to_q16(v: np.ndarray) -> np.ndarray:
    return np.floor(np.asarray(v, dtype=np.float64) * Q16_ONE + 0.5).astype(np.int32)


def from_q16(q: np.ndarray) -> np.ndarray:
    return np.asarray(q, dtype=np.float64) / Q16_ONE


# ---- reading ----------------------------------------------------------------------------------


@dataclass
class Dump:
    path: Path
    meta: dict[str, Any]
    left: np.ndarray
    right: np.ndarray
    arrays: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def width(self) -> int:
        return int(self.meta["width"])

    @property
    def height(self) -> int:
        return int(self.meta["height"])

    @property
    def config_toml(self) -> str:
        return str(self.meta.get("config_toml", ""))

    def __getitem__(self, name: str) -> np.ndarray:
        return self.arrays[name]

    def __contains__(self, name: str) -> bool:
        return name in self.arrays

    def disp(self, name: str) -> np.ndarray:
        """A disparity map in float px, NaN = invalid."""
        return q4_to_disp(self.arrays[name])


def find_dump_dir(run_dir: str | Path) -> Path:
    """RUN_DIR itself when it has meta.json, else RUN_DIR/dump; FatalError otherwise."""
    run_dir = Path(run_dir)
    if not run_dir.exists():
        raise FatalError(f"{run_dir} does not exist")
    if not run_dir.is_dir():
        raise FatalError(f"{run_dir} is not a directory")
    for candidate in (run_dir, run_dir / "dump"):
        if (candidate / "meta.json").is_file():
            return candidate
    raise FatalError(f"no dump in {run_dir}: neither {run_dir / 'meta.json'} nor {run_dir / 'dump' / 'meta.json'} exists")


def read_meta(path: Path) -> dict[str, Any]:
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise FatalError(f"cannot read {path}: {exc.strerror}") from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FatalError(f"{path} is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict):
        raise FatalError(f"{path}: expected a JSON object")
    if meta.get("format") != FORMAT:
        raise FatalError(f"{path}: format is {meta.get('format')!r}, expected {FORMAT!r}")
    if meta.get("version") != VERSION:
        raise FatalError(f"{path}: dump version {meta.get('version')!r} is not supported (this fuzzyctl reads {VERSION})")
    for key in ("width", "height"):
        if not isinstance(meta.get(key), int) or isinstance(meta.get(key), bool) or meta[key] <= 0:
            raise FatalError(f"{path}: '{key}' must be a positive integer")
    if "config_toml" in meta and not isinstance(meta["config_toml"], str):
        raise FatalError(f"{path}: 'config_toml' must be a string")
    return meta


def _load_npy(path: Path) -> np.ndarray:
    if not path.is_file():
        raise FatalError(f"dump file {path} is missing")
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise FatalError(f"dump file {path} is not a readable .npy: {exc}") from exc


def _load_png(path: Path, shape: tuple[int, int]) -> np.ndarray:
    if not path.is_file():
        raise FatalError(f"dump file {path} is missing")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise FatalError(f"dump file {path} cannot be decoded")
    if img.dtype != np.uint8 or img.ndim != 2:
        raise FatalError(f"dump file {path} must be an 8-bit grey PNG (got {img.dtype}, shape {img.shape})")
    if img.shape != shape:
        raise FatalError(f"dump file {path} is {img.shape[1]}x{img.shape[0]}, meta.json says {shape[1]}x{shape[0]}")
    return img


def read_dump(run_dir: str | Path, arrays: bool = True) -> Dump:
    """Read and check a dump (RUN_DIR or RUN_DIR/dump). Every fault names the file."""
    d = find_dump_dir(run_dir)
    meta = read_meta(d / "meta.json")
    shape = (int(meta["height"]), int(meta["width"]))
    dump = Dump(d, meta, _load_png(d / "left.png", shape), _load_png(d / "right.png", shape))
    if not arrays:
        return dump
    for name, (dtype, kind) in ARRAYS.items():
        path = d / f"{name}.npy"
        if name in OPTIONAL and not path.exists():
            continue
        a = _load_npy(path)
        if a.dtype != dtype:
            raise FatalError(f"dump file {path} has dtype {a.dtype}, expected {dtype}")
        if kind == "hw" and a.shape != shape:
            raise FatalError(f"dump file {path} has shape {a.shape}, expected {shape} (height, width)")
        if kind == "seg" and a.ndim == 2 and a.shape[1] == 4:
            # dumps written before the sub-pixel column: the painted disparity is 16 * winner
            painted = np.where(a[:, SEG_DISP] < 0, INVALID_DISP, a[:, SEG_DISP] * DISP_SCALE)
            a = np.concatenate([a, painted[:, None].astype(np.int32)], axis=1)
        if kind == "seg" and (a.ndim != 2 or a.shape[1] != SEG_COLUMNS):
            raise FatalError(f"dump file {path} has shape {a.shape}, expected (segments, {SEG_COLUMNS})")
        dump.arrays[name] = a
    for side in ("left", "right"):
        labels, seg = dump.arrays[f"labels_{side}"], dump.arrays[f"seg_{side}"]
        n = int(labels.max()) + 1 if labels.size else 0
        if labels.size and labels.min() < 0:
            raise FatalError(f"dump file {d / f'labels_{side}.npy'} has negative labels")
        if seg.shape[0] != n:
            raise FatalError(f"dump file {d / f'seg_{side}.npy'} has {seg.shape[0]} rows but labels_{side}.npy has {n} segments")
    return dump


def read_labels(dump_dir: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """labels_left.npy / labels_right.npy of a dump directory (for --labels-from)."""
    d = find_dump_dir(dump_dir)
    out = []
    for side in ("left", "right"):
        path = d / f"labels_{side}.npy"
        a = _load_npy(path)
        if a.ndim != 2 or not np.issubdtype(a.dtype, np.integer):
            raise FatalError(f"{path}: expected an integer (H, W) label image, got {a.dtype} {a.shape}")
        out.append(a.astype(np.int32))
    return out[0], out[1]


# ---- writing (the reference's results in the firmware's format) ----------------------------------


def _seg_table(dec) -> np.ndarray:
    columns = [np.asarray(dec.disparity, dtype=np.int64), to_q16(dec.score), to_q16(dec.dc1), to_q16(dec.dc2),
               disp_to_q4(dec.disparity_sub)]
    return np.stack(columns, axis=1).astype(np.int32)


def write_dump(out_dir: str | Path, result, meta_extra: dict[str, Any]) -> Path:
    """Write a :class:`fuzzyctl.reference.ReferenceResult` as OUT_DIR/meta.json + stage files."""
    d = Path(out_dir)
    d.mkdir(parents=True, exist_ok=True)
    h, w = result.left.shape
    for name, img in (("left", result.left), ("right", result.right)):
        if not cv2.imwrite(str(d / f"{name}.png"), img):
            raise FatalError(f"cannot write {d / f'{name}.png'}")
    arrays = {
        "labels_left": result.labels_left.astype(np.int32),
        "labels_right": result.labels_right.astype(np.int32),
        "seg_left": _seg_table(result.dec_left),
        "seg_right": _seg_table(result.dec_right),
        "disp_left_wta": disp_to_q4(result.disp_left_wta),
        "disp_right_wta": disp_to_q4(result.disp_right_wta),
        "lr_mask": result.lr_mask.astype(np.uint8),
        "disp_lr": disp_to_q4(result.disp_lr),
        "esr_replaced": result.esr_replaced.astype(np.uint8),
        "disp_esr": disp_to_q4(result.disp_esr),
        "densify_changed": result.densify_changed.astype(np.uint8),
        "disp_final": disp_to_q4(result.disp_final),
    }
    for name, a in arrays.items():
        dtype, _ = ARRAYS[name]
        np.save(d / f"{name}.npy", np.ascontiguousarray(a, dtype=dtype))
    meta = {"format": FORMAT, "version": VERSION, "width": int(w), "height": int(h)}
    meta.update(meta_extra)
    meta["timings_ms"] = {k: round(v, 3) for k, v in result.timings_ms.items()}
    # the one radiometric decision the comparison checks (docs/formats.md; the firmware records more)
    meta.setdefault("radiometric", {})["boundary_refined"] = bool(getattr(result, "boundary_refined", False))
    meta.setdefault("lr_check", {})["retry_recovered"] = int(getattr(result, "retry_recovered", 0))  # docs/algorithm.md 5b
    (d / "meta.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
    return d
