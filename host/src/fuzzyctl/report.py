"""Single-file HTML report of a comparison: every image is an inline base64 PNG.

Per stage: the firmware's image, the reference's image and an error heatmap; the FIS surface; a
scatter of the winners' FIS scores; and the table of figures with their tolerances.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path

import cv2
import numpy as np

from . import __version__
from .compare import Comparison

#: error heatmap: |firmware - reference| clipped at this many px
ERR_CLIP_PX = 4.0
_VALIDITY_MISMATCH = (255, 255, 0)  # BGR cyan: valid in one map, invalid in the other
_BOTH_INVALID = (40, 40, 40)


def image_data_uri(img: np.ndarray) -> str:
    """An 8-bit image as an inline PNG (data URI)."""
    ok, buf = cv2.imencode(".png", img)
    if not ok:  # pragma: no cover - OpenCV always encodes uint8 images
        raise RuntimeError("PNG encoding failed")
    return "data:image/png;base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def colour_disparity(disp: np.ndarray, max_disp: float) -> np.ndarray:
    """TURBO colour map of a float disparity map, invalid (NaN) black."""
    valid = ~np.isnan(disp)
    v = np.clip(np.where(valid, disp, 0.0) / max(max_disp, 1e-9) * 255.0, 0, 255).astype(np.uint8)
    out = cv2.applyColorMap(v, cv2.COLORMAP_TURBO)
    out[~valid] = 0
    return out


def error_heatmap(a: np.ndarray, b: np.ndarray, clip: float = ERR_CLIP_PX) -> np.ndarray:
    """|a - b| (INFERNO, 0 .. clip px); validity mismatch cyan, both invalid dark grey."""
    va, vb = ~np.isnan(a), ~np.isnan(b)
    both = va & vb
    e = np.where(both, np.abs(np.where(va, a, 0) - np.where(vb, b, 0)), 0.0)
    out = cv2.applyColorMap((np.clip(e / clip, 0, 1) * 255).astype(np.uint8), cv2.COLORMAP_INFERNO)
    out[va != vb] = _VALIDITY_MISMATCH
    out[~va & ~vb] = _BOTH_INVALID
    return out


def mask_image(mask: np.ndarray) -> np.ndarray:
    return np.where(mask, 255, 0).astype(np.uint8)


def mask_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """White where the masks agree on 1, black on 0, red where only a, blue where only b."""
    out = np.zeros(a.shape + (3,), dtype=np.uint8)
    out[a & b] = (255, 255, 255)
    out[a & ~b] = (0, 0, 255)
    out[~a & b] = (255, 0, 0)
    return out


def boundaries(grey: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """The grey image with segment boundaries in red."""
    out = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
    edge = np.zeros(labels.shape, dtype=bool)
    edge[:, 1:] |= labels[:, 1:] != labels[:, :-1]
    edge[1:, :] |= labels[1:, :] != labels[:-1, :]
    out[edge] = (0, 0, 255)
    return out


def figure_data_uri(fig, dpi: int = 90, tight: bool = False) -> str:
    """A matplotlib figure as an inline PNG (data URI); closes the figure."""
    from .plots import png_bytes

    return "data:image/png;base64," + base64.b64encode(png_bytes(fig, dpi, tight)).decode("ascii")


def _score_scatter(c: Comparison):
    import matplotlib.pyplot as plt

    from . import dump as dumpmod

    fig, ax = plt.subplots(figsize=(4.6, 4.2), constrained_layout=True)
    for side, colour in (("left", "tab:blue"), ("right", "tab:orange")):
        if c.metric(f"seg_winner_agreement_{side}_pct").value is None:
            continue
        seg = c.dump[f"seg_{side}"]
        dec = getattr(c.reference, f"dec_{side}")
        same = seg[:, dumpmod.SEG_DISP] == dec.disparity
        fw = dumpmod.from_q16(seg[:, dumpmod.SEG_SCORE])
        ax.scatter(dec.score[same], fw[same], s=4, c=colour, label=f"{side}, same winner")
        ax.scatter(dec.score[~same], fw[~same], s=14, marker="x", c="red" if side == "left" else "darkred",
                   label=f"{side}, different winner")
    ax.plot([0, 1], [0, 1], "k--", lw=0.8)
    ax.set_xlabel("reference FIS score (scikit-fuzzy)")
    ax.set_ylabel("firmware FIS score (LUT, Q16)")
    ax.set_title("winning FIS score per segment")
    ax.legend(fontsize=7)
    return fig


def _row(title: str, images: list[tuple[str, np.ndarray]], note: str = "") -> str:
    cells = "".join(
        f'<figure><img src="{image_data_uri(img)}" alt="{html.escape(cap)}"><figcaption>{html.escape(cap)}</figcaption></figure>'
        for cap, img in images
    )
    note_html = f'<p class="note">{html.escape(note)}</p>' if note else ""
    return f'<section><h2>{html.escape(title)}</h2>{note_html}<div class="row">{cells}</div></section>'


def _fmt(v: float | None, unit: str) -> str:
    if v is None:
        return "n/a"
    if unit == "%":
        return f"{v:.3f} %"
    return f"{v:.3g}"


def render(c: Comparison) -> str:
    d, r = c.dump, c.reference
    D = c.config.cost.max_disparity
    fw = {name: d.disp(name) for name in ("disp_left_wta", "disp_right_wta", "disp_lr", "disp_final")}
    failures = {m.name for m, _ in c.failures()}
    verdict = "PASS" if c.passed else f"FAIL ({len(failures)} metric(s) outside tolerance)"

    rows = []
    for m in c.metrics:
        tol = c.tolerances.get(m.name)
        status = "" if tol is None else ("n/a" if m.value is None else ("fail" if m.name in failures else "ok"))
        rows.append(
            f'<tr class="{status}"><td>{html.escape(m.stage)}</td><td><code>{m.name}</code></td>'
            f"<td>{_fmt(m.value, m.unit)}</td><td>{html.escape(tol.text()) if tol else ''}</td>"
            f"<td>{status}</td><td>{html.escape(m.doc)}</td></tr>"
        )
    table = (
        "<table><tr><th>stage</th><th>metric</th><th>value</th><th>tolerance</th><th>status</th><th>meaning</th></tr>"
        + "".join(rows)
        + "</table>"
    )

    sections = [
        _row("Inputs (as matched)", [("left", d.left), ("right", d.right)]),
        _row(
            "Segmentation",
            [("firmware, left", boundaries(d.left, d["labels_left"])), ("reference, left", boundaries(r.left, r.labels_left))],
            "The reference reused the firmware's labels." if r.labels_given else "The reference ran its own SLIC.",
        ),
    ]
    for key, ref_map, title in (
        ("disp_left_wta", r.disp_left_wta, "WTA, left reference"),
        ("disp_right_wta", r.disp_right_wta, "WTA, right reference"),
        ("disp_lr", r.disp_lr, "After the left-right check, eq. (13)"),
        ("disp_final", r.disp_final, "Final, after ESR, eq. (14)-(15)"),
    ):
        sections.append(
            _row(
                title,
                [
                    ("firmware", colour_disparity(fw[key], D)),
                    ("reference", colour_disparity(ref_map, D)),
                    (f"|firmware - reference| (0..{ERR_CLIP_PX:g} px; cyan = validity differs)", error_heatmap(fw[key], ref_map)),
                ],
            )
        )
    sections.append(
        _row(
            "Masks",
            [
                ("LR mask: white both, red firmware only, blue reference only", mask_diff(d["lr_mask"] != 0, r.lr_mask)),
                ("ESR replaced: white both, red firmware only, blue reference only", mask_diff(d["esr_replaced"] != 0, r.esr_replaced)),
            ],
        )
    )

    from .plots import surface_figure

    plots = (
        '<section><h2>FIS</h2><div class="row">'
        f'<figure><img src="{figure_data_uri(surface_figure(c.fis, 61))}" alt="FIS surface"><figcaption>FIS surface ({html.escape(c.fis.defn.name)})</figcaption></figure>'
        f'<figure><img src="{figure_data_uri(_score_scatter(c))}" alt="scores"><figcaption>winning scores, firmware vs reference</figcaption></figure>'
        "</div></section>"
    )
    ignored = ""
    if c.ignored_config:
        items = ", ".join(f"{k} = {v!r}" for k, v in c.ignored_config.items())
        ignored = f'<p class="note">Config keys of the firmware that the reference does not model (ignored): {html.escape(items)}</p>'
    timings = json.dumps({"firmware": d.meta.get("timings_ms", {}), "reference": {k: round(v, 1) for k, v in r.timings_ms.items()}})

    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>fuzzystereo compare — {html.escape(str(d.path))}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 1.5em; color: #222; }}
h1 {{ font-size: 1.4em; }} h2 {{ font-size: 1.1em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }}
.verdict {{ font-weight: bold; padding: .3em .6em; display: inline-block; }}
.pass {{ background: #d7f5d7; }} .failv {{ background: #f8d0d0; }}
table {{ border-collapse: collapse; font-size: .9em; }} td, th {{ border: 1px solid #ccc; padding: .2em .5em; text-align: left; }}
tr.fail td {{ background: #f8d0d0; }} tr.ok td:nth-child(5) {{ color: #070; }}
.row {{ display: flex; flex-wrap: wrap; gap: 1em; }} figure {{ margin: 0; }}
figure img {{ max-width: 460px; image-rendering: pixelated; border: 1px solid #ddd; }}
figcaption {{ font-size: .8em; color: #555; max-width: 460px; }} .note {{ color: #555; font-size: .9em; }}
pre {{ background: #f6f6f6; padding: .5em; font-size: .85em; }}
</style></head><body>
<h1>fuzzystereo: firmware vs float64 reference</h1>
<p class="verdict {'pass' if c.passed else 'failv'}">{html.escape(verdict)}</p>
<p>dump <code>{html.escape(str(d.path))}</code> — firmware {html.escape(str(d.meta.get('firmware_version', '?')))},
{d.width}x{d.height}, D = {D}, FIS {html.escape(c.fis.defn.name)}; inputs {html.escape(str(d.meta.get('left', '')))} /
{html.escape(str(d.meta.get('right', '')))}; report by fuzzyctl {__version__}.</p>
{ignored}
<h2>Figures</h2>
{table}
{''.join(sections)}
{plots}
<h2>Config (from the dump)</h2><pre>{html.escape(c.config.to_toml())}</pre>
<h2>Timings [ms]</h2><pre>{html.escape(timings)}</pre>
</body></html>
"""


def write_report(c: Comparison, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(render(c), encoding="utf-8")
    return path


def write_index(summaries, out_dir: str | Path, title: str) -> Path:
    """``out_dir/index.html``: one row per frame of a dataset comparison, linking its report."""
    out_dir = Path(out_dir)
    rows = []
    for s in summaries:
        link = Path(s.report).relative_to(out_dir).as_posix() if s.report else ""
        name = f'<a href="{html.escape(link)}">{html.escape(s.frame.key)}</a>' if link else html.escape(s.frame.key)
        status = "ok" if s.passed else "FAIL: " + html.escape("; ".join(s.failures))
        rows.append(f"<tr><td>{name}</td><td>{s.width}x{s.height}</td><td>{s.frame.max_disparity}</td>"
                    f"<td>{s.winner_left_pct:.2f}</td><td>{s.winner_right_pct:.2f}</td>"
                    f"<td>{s.valid_within_1px_pct:.2f}</td><td>{s.final_within_1px_pct:.2f}</td><td>{status}</td></tr>")
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>fuzzyctl compare — {html.escape(title)}</title>
<style>body{{font-family:sans-serif}} td,th{{padding:2px 8px;text-align:right}} td:first-child{{text-align:left}}</style>
</head><body><h1>firmware vs reference — {html.escape(title)}</h1>
<p>fuzzyctl {__version__}; per-frame reports link from the frame name.</p>
<table><tr><th>frame</th><th>size</th><th>D</th><th>winner L %</th><th>winner R %</th>
<th>final ±1 px % (valid)</th><th>final ±1 px % (all)</th><th>status</th></tr>
{''.join(rows)}</table></body></html>
"""
    path = out_dir / "index.html"
    path.write_text(page, encoding="utf-8")
    return path
