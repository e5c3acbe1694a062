"""HTML report of a detection evaluation (``fuzzystereo detect-eval --json FILE``).

Reads the evaluation JSON (per type, overall and per frame: detections, missed ground-truth obstacles,
false-positive boxes) and the generated set it was run on (``training/image_2/NAME.png`` and
``training/sim_gt/NAME.json``, docs/simulator.md), and writes one self-contained HTML page (every
picture an inline JPEG):

- the per-type table (detected %, false positives per frame, road and sky IoU, distance error);
- every miss classified by the detection that overlaps it most (``classify_miss``): *none* (nothing
  over it), *merged* (a larger box over it, and over a neighbour when ``neighbour`` is set), *fragment*
  (a box inside it), *offset* (a partial overlap), *distance* (IoU reached, distance off);
- the worst frames (most misses and false positives first): the left image with every ground-truth
  obstacle (white, yellow when missed), the detections that matched (green) and the false positives
  (red), each labelled with its distance.

With ``--against BASE.json`` (the same set evaluated with another build or config) the page also says,
frame by frame, which obstacles the evaluation gained or lost against the base and how the false
positives changed, and shows those frames first — what a detector change did, rather than only its
totals.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .errors import FatalError, load_json

Box = tuple[int, int, int, int]

MISS_CLASSES = ("none", "merged, with a neighbour", "merged", "fragment", "offset", "distance")


def load_eval(path: Path) -> dict[str, Any]:
    """A detect-eval JSON; FatalError naming the file when it is missing, not JSON or not detect-eval's."""
    path = Path(path)
    if not path.is_file():
        raise FatalError(f"{path}: not found (write one with 'fuzzystereo detect-eval --json {path.name}')")
    doc = load_json(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("frames"), list) or "overall" not in doc:
        raise FatalError(f"{path}: not a 'fuzzystereo detect-eval --json' file (no 'frames' list or 'overall')")
    for i, f in enumerate(doc["frames"]):
        for key in ("frame", "type", "detections", "missed", "false_positive_boxes"):
            if key not in f:
                raise FatalError(f"{path}: frames[{i}] has no '{key}' (written by an older detect-eval?)")
    return doc


def _area(b: Box) -> int:
    return max(1, (b[2] - b[0]) * (b[3] - b[1]))


def _inter(a: Box, b: Box) -> int:
    return max(0, min(a[2], b[2]) - max(a[0], b[0])) * max(0, min(a[3], b[3]) - max(a[1], b[1]))


def _iou(a: Box, b: Box) -> float:
    i = _inter(a, b)
    return i / (_area(a) + _area(b) - i)


def classify_miss(miss: dict[str, Any], detections: list[dict[str, Any]], gt: list[dict[str, Any]],
                  min_iou: float = 0.5) -> str:
    """Class of a missed ground-truth obstacle by the detection of largest IoU with it (one of MISS_CLASSES).
    merged: that box covers > 80 % of the obstacle and is less than 60 % on it; "with a neighbour" when it also
    covers >= 30 % of another ground-truth obstacle's box. fragment: the box lies > 80 % on the obstacle and
    covers < 60 % of it. offset: any other overlap of IoU 0.1-min_iou; distance: IoU >= min_iou (so the distance
    was off); none: no detection with IoU >= 0.1."""
    g = tuple(miss["box"])
    if not detections:
        return "none"
    best = max(detections, key=lambda d: _iou(tuple(d["box"]), g))
    b = tuple(best["box"])
    iou = _iou(b, g)
    if iou < 0.1:
        return "none"
    if iou >= min_iou:
        return "distance"
    cover, on = _inter(b, g) / _area(g), _inter(b, g) / _area(b)
    if cover > 0.8 and on < 0.6:
        others = [o for o in gt if o.get("id") != miss.get("id") and o.get("visible_pixels", 0) > 0 and o.get("box")
                  and _inter(b, tuple(o["box"])) >= 0.3 * _area(tuple(o["box"]))]
        return "merged, with a neighbour" if others else "merged"
    if on > 0.8 and cover < 0.6:
        return "fragment"
    return "offset"


def _jpeg_uri(img: np.ndarray) -> str:
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 85])
    if not ok:
        raise FatalError("could not encode a frame picture")
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def _label(img: np.ndarray, text: str, x: int, y: int, colour: tuple[int, int, int]) -> None:
    y = max(10, y)
    cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, 0.38, colour, 1, cv2.LINE_AA)


def frame_picture(image: np.ndarray, frame: dict[str, Any], gt: list[dict[str, Any]]) -> np.ndarray:
    """The left image with the ground truth (white; missed: yellow), matched detections (green) and false
    positives (red), distances in metres."""
    img = image.copy()
    missed = {m.get("id") for m in frame["missed"]}
    for o in gt:
        if not o.get("box") or o.get("visible_pixels", 0) <= 0:
            continue
        x0, y0, x1, y1 = o["box"]
        colour = (0, 230, 255) if o.get("id") in missed else (255, 255, 255)
        cv2.rectangle(img, (x0, y0), (x1, y1), colour, 1)
        _label(img, f"{o['distance_m']:.1f}", x0 + 2, y1 - 3, colour)
    fp = [tuple(b["box"]) for b in frame["false_positive_boxes"]]
    for d in frame["detections"]:
        x0, y0, x1, y1 = d["box"]
        colour = (40, 40, 230) if tuple(d["box"]) in fp else (60, 200, 60)
        cv2.rectangle(img, (x0, y0), (x1, y1), colour, 2)
        _label(img, f"{d['distance_m']:.1f} m", x0 + 2, y0 - 3, colour)
    return img


def _frame_files(dataset: Path, name: str) -> tuple[Path, Path]:
    tr = Path(dataset) / "training"
    return tr / "image_2" / f"{name}.png", tr / "sim_gt" / f"{name}.json"


def _gt(dataset: Path, name: str) -> list[dict[str, Any]]:
    _, gt_file = _frame_files(dataset, name)
    if not gt_file.is_file():
        raise FatalError(f"{gt_file}: not found (is {dataset} the set the evaluation ran on?)")
    return json.loads(gt_file.read_text()).get("obstacles", [])


def _changes(base: dict[str, Any] | None, frame: dict[str, Any]) -> tuple[list[int], list[int], int]:
    """(gained ids, lost ids, false positives new - base) of a frame against the base's frame."""
    if base is None:
        return [], [], 0
    mb = {m.get("id") for m in base["missed"]}
    mn = {m.get("id") for m in frame["missed"]}
    return (sorted(mb - mn), sorted(mn - mb),
            len(frame["false_positive_boxes"]) - len(base["false_positive_boxes"]))


def _pct(v: Any) -> str:
    return "-" if v is None else f"{100.0 * float(v):.1f}"


def _num(v: Any, fmt: str = "{:.2f}") -> str:
    return "-" if v is None else fmt.format(float(v))


def write_detect_report(eval_json: Path, out: Path, dataset: Path | None = None, against: Path | None = None,
                        max_frames: int = 30) -> tuple[Path, int]:
    """Writes the HTML page; returns (path, frames pictured)."""
    doc = load_eval(eval_json)
    base_doc = load_eval(against) if against is not None else None
    dataset = Path(dataset) if dataset is not None else Path(doc.get("dataset", ""))
    if not (dataset / "training" / "sim_gt").is_dir():
        raise FatalError(f"{dataset}: no training/sim_gt folder (give the generated set with --dataset)")
    base_frames: dict[str, dict[str, Any]] = {}
    if base_doc is not None:
        base_frames = {f["frame"]: f for f in base_doc["frames"]}
        missing = [f["frame"] for f in doc["frames"] if f["frame"] not in base_frames]
        if missing:
            raise FatalError(f"{against}: has no frame {missing[0]} of {eval_json} (not the same set?)")

    # Miss classes over all frames (and per frame, for the captions).
    counts = {c: 0 for c in MISS_CLASSES}
    frame_rows = []
    for f in doc["frames"]:
        gt = _gt(dataset, f["frame"])
        classes = [classify_miss(m, f["detections"], gt) for m in f["missed"]]
        for c in classes:
            counts[c] += 1
        gained, lost, dfp = _changes(base_frames.get(f["frame"]), f)
        frame_rows.append((f, gt, classes, gained, lost, dfp))

    # Order: frames a change touched first (with --against), then by misses + false positives.
    def order(row):
        f, _, _, gained, lost, dfp = row
        changed = bool(gained or lost or dfp)
        return (not changed, -(len(f["missed"]) + len(f["false_positive_boxes"])), f["frame"])

    frame_rows.sort(key=order)
    e = html.escape
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>detection report</title><style>",
        "body{font-family:sans-serif;margin:1.5em;max-width:1400px} table{border-collapse:collapse;margin:0.5em 0}",
        "td,th{border:1px solid #bbb;padding:2px 8px;text-align:right} th{background:#eee}",
        "td.l,th.l{text-align:left} .fr{display:inline-block;margin:6px;vertical-align:top;width:648px}",
        ".fr img{width:640px} .cap{font-size:12px} .better{color:#070} .worse{color:#a00}</style></head><body>",
        f"<h1>Detection: {e(str(eval_json))}</h1>",
        f"<p>Set {e(str(dataset))}; criteria {e(json.dumps(doc.get('criteria', {})))}. Boxes: white = ground truth, "
        "yellow = missed ground truth, green = detection that matched, red = false positive (distances in m).</p>",
    ]
    # Per-type table (and the base's beside it).
    parts.append("<h2>Per scenario type</h2><table><tr><th class='l'>type</th><th>frames</th><th>GT</th>"
                 "<th>detected %</th><th>FP / frame</th><th>road IoU</th><th>sky IoU</th><th>dZ median %</th>"
                 + ("<th>base detected %</th><th>base FP / frame</th>" if base_doc else "") + "</tr>")
    types = dict(doc.get("per_type", {}))
    types["overall"] = doc["overall"]
    base_types = dict(base_doc.get("per_type", {})) if base_doc else {}
    if base_doc:
        base_types["overall"] = base_doc["overall"]
    for name, m in types.items():
        b = base_types.get(name, {})
        parts.append(
            f"<tr><td class='l'>{e(name)}</td><td>{m.get('frames', '-')}</td><td>{m.get('gt_obstacles', '-')}</td>"
            f"<td>{_pct(m.get('detection_rate'))}</td><td>{_num(m.get('false_positives_per_frame'))}</td>"
            f"<td>{_num(m.get('road_iou'), '{:.3f}')}</td><td>{_num(m.get('sky_iou'), '{:.3f}')}</td>"
            f"<td>{_num(m.get('distance_rel_error_median') * 100 if m.get('distance_rel_error_median') is not None else None, '{:.1f}')}</td>"
            + (f"<td>{_pct(b.get('detection_rate'))}</td><td>{_num(b.get('false_positives_per_frame'))}</td>"
               if base_doc else "") + "</tr>")
    parts.append("</table>")
    parts.append("<h2>Misses by class</h2><table><tr><th class='l'>class</th><th>misses</th></tr>")
    for c in MISS_CLASSES:
        parts.append(f"<tr><td class='l'>{e(c)}</td><td>{counts[c]}</td></tr>")
    parts.append("</table><p class='cap'>The class of a miss is given by the detection of largest IoU with it: "
                 "merged = a larger box over it (with a neighbour: the box also covers another obstacle), fragment "
                 "= a box inside it, offset = a partial overlap, distance = IoU reached but the distance was off, "
                 "none = nothing over it.</p>")
    if base_doc is not None:
        g = sum(len(r[3]) for r in frame_rows)
        lo = sum(len(r[4]) for r in frame_rows)
        fp_up = sum(max(r[5], 0) for r in frame_rows)
        fp_down = sum(max(-r[5], 0) for r in frame_rows)
        parts.append(f"<h2>Against {e(str(against))}</h2><p>{g} obstacles gained, {lo} lost; false positives "
                     f"{fp_up} added, {fp_down} removed (frame by frame); "
                     f"{sum(1 for r in frame_rows if r[3] or r[4] or r[5])} frames changed.</p>")
    shown = 0
    parts.append("<h2>Frames</h2>")
    for f, gt, classes, gained, lost, dfp in frame_rows:
        if shown >= max_frames:
            break
        if not f["missed"] and not f["false_positive_boxes"] and not (gained or lost or dfp):
            continue
        img_file, _ = _frame_files(dataset, f["frame"])
        img = cv2.imread(str(img_file), cv2.IMREAD_COLOR)
        if img is None:
            raise FatalError(f"{img_file}: not found or not an image")
        pic = frame_picture(img, f, gt)
        by_id = {o.get("id"): o for o in gt}
        miss_txt = ", ".join(f"#{m.get('id')} {by_id.get(m.get('id'), {}).get('shape', '?')} "
                             f"{m['distance_m']:.1f} m ({c})" for m, c in zip(f["missed"], classes)) or "none"
        change = ""
        if base_doc is not None and (gained or lost or dfp):
            change = (f"<br><span class='better'>gained {gained}</span> " if gained else "<br>") + \
                     (f"<span class='worse'>lost {lost}</span> " if lost else "") + \
                     (f"false positives {dfp:+d}" if dfp else "")
        parts.append(f"<div class='fr'><img src='{_jpeg_uri(pic)}' alt='{e(f['frame'])}'><div class='cap'>"
                     f"<b>{e(f['frame'])}</b> ({e(f['type'])}): {f.get('detected', '?')} of "
                     f"{f.get('gt_obstacles', '?')} found, {len(f['false_positive_boxes'])} false positives; "
                     f"missed: {e(miss_txt)}{change}</div></div>")
        shown += 1
    if shown == 0:
        parts.append("<p>No frame with a miss, a false positive or a change.</p>")
    parts.append("</body></html>")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(parts))
    return out, shown
