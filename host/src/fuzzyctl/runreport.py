"""HTML report of one robot run (``fuzzystereo run --record DIR`` / ``make demo``).

Reads the run record (docs/formats.md, "Run record"):

- ``DIR/run.json``: source, start, goal, robot radius, the world's obstacles (simulator runs),
  the result and stage-timing statistics;
- ``DIR/frames.jsonl``: one JSON object per frame (pose, command, detections, tracks, stage ms);
- ``DIR/frames/NNNNNN_*.png``: annotated snapshots of some frames.

and writes one self-contained HTML file (every picture an inline PNG): the trajectory plot
(estimated and true robot path, obstacles with their motion, track estimates, start and goal),
the annotated frames, the stage timings and the per-frame speed and distance plots.
"""

from __future__ import annotations

import base64
import html
import json
import math
from pathlib import Path
from typing import Any

from .errors import FatalError
from .report import figure_data_uri
from .simworld import obstacle_state


def load_run(run_dir: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """(run.json, frames) of a run record; FatalError naming the file when missing or malformed."""
    run_dir = Path(run_dir)
    run_file = run_dir / "run.json"
    frames_file = run_dir / "frames.jsonl"
    if not run_file.is_file():
        raise FatalError(f"{run_file}: not found (is {run_dir} a 'fuzzystereo run --record' directory?)")
    try:
        run = json.loads(run_file.read_text())
    except json.JSONDecodeError as exc:
        raise FatalError(f"{run_file}: not valid JSON: {exc}") from exc
    frames: list[dict[str, Any]] = []
    if frames_file.is_file():
        for n, line in enumerate(frames_file.read_text().splitlines(), 1):
            if not line.strip():
                continue
            try:
                frames.append(json.loads(line))
            except json.JSONDecodeError:
                # A run cut off mid-write (power loss, SIGKILL) leaves a partial last line: keep
                # everything before it, refuse corruption anywhere else.
                if n == len(frames_file.read_text().splitlines()):
                    break
                raise FatalError(f"{frames_file}:{n}: not valid JSON") from None
    return run, frames


def load_run_config(run_dir: Path) -> dict[str, dict[str, Any]]:
    """A run record's config.toml (the whole configuration the run used; defaults where it is silent)."""
    from .config import parse_config

    path = Path(run_dir) / "config.toml"
    if not path.is_file():
        raise FatalError(f"{path}: not found (the run's configuration; is {run_dir} a --record directory?)")
    return parse_config(path.read_text(), str(path), strict=False, ignored={}).as_dict()


def _fig_png(fig) -> str:
    return figure_data_uri(fig, dpi=110, tight=True)


def _file_png(path: Path) -> str:
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _obstacle_patch(o: dict[str, Any], t: float, **style):
    from matplotlib.patches import Circle, Polygon

    x, y, _, _ = obstacle_state(o, t)
    if o.get("shape") == "box":
        L, W = o.get("length", 0.5), o.get("width", 0.5)
        c, s = math.cos(o.get("yaw", 0.0)), math.sin(o.get("yaw", 0.0))
        pts = [(x + c * dx - s * dy, y + s * dx + c * dy) for dx, dy in ((L / 2, W / 2), (-L / 2, W / 2), (-L / 2, -W / 2), (L / 2, -W / 2))]
        return Polygon(pts, closed=True, **style)
    return Circle((x, y), o.get("radius", 0.25), **style)


def plan_view(frames: list[dict[str, Any]]) -> tuple[list[list[float]], list[list[float]]] | None:
    """The planner's static world in the last frame that recorded it: (map cells, fitted bodies) as [x, y, r]
    lists (``plan_obstacles`` with ``plan_kinds`` m / f and b); None when no frame has them."""
    for f in reversed(frames):
        obs, kinds = f.get("plan_obstacles"), f.get("plan_kinds")
        if obs is None or kinds is None:
            continue
        cells = [o for o, k in zip(obs, kinds) if k in "mf"]
        bodies = [o for o, k in zip(obs, kinds) if k == "b"]
        return cells, bodies
    return None


def trajectory_figure(run: dict[str, Any], frames: list[dict[str, Any]]):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from matplotlib.patches import Circle

    fig, ax = plt.subplots(figsize=(8, 6.5))
    t_end = frames[-1]["t"] if frames else 0.0
    for o in run.get("world", {}).get("obstacles", []):
        moving = abs(o.get("vx", 0.0)) + abs(o.get("vy", 0.0)) > 1e-9
        if moving:
            ax.add_patch(_obstacle_patch(o, 0.0, facecolor="none", edgecolor="0.5", linestyle="--"))
            ax.add_patch(_obstacle_patch(o, t_end, facecolor="0.6", edgecolor="k", alpha=0.8))
            # its walk (straight, or with the turns of a solid mover), the arrow at the end
            ts = [t_end * k / 50 for k in range(51)]
            walk = [obstacle_state(o, t)[:2] for t in ts]
            ax.plot([p[0] for p in walk], [p[1] for p in walk], color="0.4", linewidth=0.8)
            ax.annotate("", xy=walk[-1], xytext=walk[-2] if walk[-2] != walk[-1] else (o["x"], o["y"]),
                        arrowprops=dict(arrowstyle="->", color="0.4"))
        else:
            ax.add_patch(_obstacle_patch(o, 0.0, facecolor="0.35", edgecolor="k"))
    # Track estimates: confirmed tracks' positions over the run, one colour per track id.
    cmap = plt.get_cmap("tab10")
    tracks: dict[int, list[tuple[float, float]]] = {}
    for f in frames:
        for tr in f.get("tracks", []):
            if tr.get("confirmed", True):
                tracks.setdefault(int(tr["id"]), []).append((tr["p"][0], tr["p"][1]))
    for i, (tid, pts) in enumerate(sorted(tracks.items())):
        xs, ys = zip(*pts)
        ax.scatter(xs, ys, s=4, color=cmap(i % 10), alpha=0.5, label="tracks" if i == 0 else None)
    # What the planner saw in the last frame that recorded it (every 10th frame): the map's cells as dots and
    # the bodies fitted to them (kind b, [loop] body_fit) as dashed circles — beside the true obstacles above.
    planned = plan_view(frames)
    if planned is not None:
        cells, bodies = planned
        if cells:
            ax.scatter([c[0] for c in cells], [c[1] for c in cells], s=2, color="tab:purple", alpha=0.6,
                       label="map cells (last plan)")
        for i, (bx, by, br) in enumerate(bodies):
            ax.add_patch(Circle((bx, by), br, fill=False, color="tab:pink", linestyle="--", lw=1.5,
                                label="bodies (last plan)" if i == 0 else None))
    if frames:
        if all("true_pose" in f for f in frames):
            tx = [f["true_pose"][0] for f in frames]
            ty = [f["true_pose"][1] for f in frames]
            ax.plot(tx, ty, "-", color="tab:blue", lw=2, label="robot (true)")
        ex = [f["pose"][0] for f in frames]
        ey = [f["pose"][1] for f in frames]
        ax.plot(ex, ey, "--", color="tab:orange", lw=1.2, label="robot (odometry)")
        last = frames[-1].get("true_pose", frames[-1]["pose"])
        ax.add_patch(Circle((last[0], last[1]), run.get("robot_radius_m", 0.2), fill=False, color="tab:blue"))
    start = run.get("start")
    goal = run.get("goal")
    if start:
        ax.plot(start[0], start[1], "o", color="tab:green", ms=9, label="start")
    if goal:
        ax.plot(goal[0], goal[1], "*", color="tab:red", ms=14, label="goal")
    # View: start, goal, the robot's path and the world's obstacles, plus a margin. Tracks that
    # coasted far away (a spurious velocity estimate out of view) must not shrink the picture.
    xs = [p[0] for p in ([start] if start else []) + ([goal] if goal else [])]
    ys = [p[1] for p in ([start] if start else []) + ([goal] if goal else [])]
    for f in frames:
        p = f.get("true_pose", f["pose"])
        xs.append(p[0])
        ys.append(p[1])
    for o in run.get("world", {}).get("obstacles", []):
        xs.append(o.get("x", 0.0))
        ys.append(o.get("y", 0.0))
    if xs:
        m = 1.0
        ax.set_xlim(min(xs) - m, max(xs) + m)
        ax.set_ylim(min(ys) - m, max(ys) + m)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (forward)")
    ax.set_ylabel("y [m] (left)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    status = run.get("result", {}).get("status", "?")
    ax.set_title(f"{run.get('scenario', '')}  —  {status}")
    return fig


def series_figure(frames: list[dict[str, Any]]):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 4.5), sharex=True)
    t = [f["t"] for f in frames]
    a1.plot(t, [f.get("cmd", [0, 0])[0] for f in frames], label="v [m/s]")
    a1.plot(t, [f.get("cmd", [0, 0])[1] for f in frames], label="ω [rad/s]")
    a1.legend(fontsize=8)
    a1.grid(True, alpha=0.3)
    nearest = [min((d["distance_m"] for d in f.get("detections", [])), default=float("nan")) for f in frames]
    a2.plot(t, nearest, ".", ms=3, color="tab:red", label="nearest detection [m]")
    a2.set_xlabel("t [s]")
    a2.legend(fontsize=8)
    a2.grid(True, alpha=0.3)
    return fig


def timing_figure(run: dict[str, Any]):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    stats = run.get("timing_ms", {})
    names = list(stats)
    fig, ax = plt.subplots(figsize=(8, 0.45 * max(len(names), 2) + 0.8))
    med = [stats[n].get("median", 0.0) for n in names]
    p90 = [stats[n].get("p90", 0.0) for n in names]
    ax.barh(names, p90, color="0.8", label="p90")
    ax.barh(names, med, color="tab:blue", label="median")
    ax.invert_yaxis()
    ax.set_xlabel("ms per frame")
    ax.legend(fontsize=8)
    ax.grid(True, axis="x", alpha=0.3)
    return fig


def write_report(run_dir: Path, out: Path, max_frames: int = 6) -> Path:
    run, frames = load_run(run_dir)
    run_dir = Path(run_dir)
    res = run.get("result", {})
    rows = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(_fmt(v))}</td></tr>" for k, v in res.items())
    stats = run.get("timing_ms", {})
    trows = "".join(
        f"<tr><th>{html.escape(k)}</th><td>{v.get('median', 0):.1f}</td><td>{v.get('p90', 0):.1f}</td><td>{v.get('max', 0):.1f}</td></tr>"
        for k, v in stats.items()
    )
    snaps = sorted((run_dir / "frames").glob("*_overlay.png")) if (run_dir / "frames").is_dir() else []
    if len(snaps) > max_frames:
        idx = [round(i * (len(snaps) - 1) / (max_frames - 1)) for i in range(max_frames)]
        snaps = [snaps[i] for i in idx]
    frame_html = ""
    for s in snaps:
        stem = s.name[: -len("_overlay.png")]
        disp = s.with_name(stem + "_disp.png")
        frame_html += f"<figure><img src='{_file_png(s)}'>"
        if disp.is_file():
            frame_html += f"<img src='{_file_png(disp)}'>"
        frame_html += f"<figcaption>frame {html.escape(stem)}: obstacles boxed red (near) / green (mid) / blue (far), disparity TURBO</figcaption></figure>"
    parts = [
        "<!doctype html><meta charset='utf-8'><title>fuzzystereo run</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}td,th{padding:2px 8px;text-align:left}"
        "img{max-width:100%;margin:2px}figure{margin:8px 0}</style>",
        f"<h1>fuzzystereo run — {html.escape(str(run.get('scenario', run.get('source', ''))))}</h1>",
        f"<p>source <code>{html.escape(str(run.get('source', '')))}</code>, {len(frames)} frames</p>",
        f"<h2>Result</h2><table>{rows}</table>",
        f"<h2>Trajectory</h2><img src='{_fig_png(trajectory_figure(run, frames))}'>",
    ]
    if frames:
        parts.append(f"<h2>Commands and nearest obstacle</h2><img src='{_fig_png(series_figure(frames))}'>")
    faults = perception_fault_spans(frames)
    if faults:
        frows = "".join(f"<tr><td>{a}-{b}</td><td>{html.escape(msg)}</td></tr>" for a, b, msg in faults)
        parts.append("<h2>Perception faults</h2><p>Frames the perception failsafe found blind or frozen "
                     "(kept out of the map and the tracker; the motors stop after <code>[perception] trip_frames</code> in a row).</p>"
                     f"<table><tr><th>frames</th><th>fault (first frame)</th></tr>{frows}</table>")
    mism = camera_mismatch_spans(frames)
    if mism:
        mrows = "".join(f"<tr><td>{a}-{b}</td><td>{html.escape(what)}</td></tr>" for a, b, what in mism)
        parts.append("<h2>Camera mismatch</h2><p>Frames whose pair the matcher's camera-difference checks read as "
                     "mismatched (docs/algorithm.md 2b, 2c; docs/runtime.md): the cameras differ in exposure, gain, tone or "
                     "noise. Give both the same fixed exposure and gain, and check with <code>fuzzyctl rectcheck</code>.</p>"
                     f"<table><tr><th>frames</th><th>what (first frame)</th></tr>{mrows}</table>")
    parts.append("<h2>Stage timings</h2><table><tr><th>stage</th><th>median ms</th><th>p90 ms</th><th>max ms</th></tr>" + trows + "</table>")
    if stats:
        parts.append(f"<img src='{_fig_png(timing_figure(run))}'>")
    if frame_html:
        parts.append("<h2>Annotated frames</h2>" + frame_html)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(parts))
    return out


def _frame_spans(frames: list[dict[str, Any]], key: str, describe) -> list[tuple[int, int, str]]:
    """Runs of consecutive frames whose record has ``key``: (first frame, last frame, describe(first entry))."""
    spans: list[tuple[int, int, str]] = []
    prev = None
    for f in frames:
        v = f.get(key)
        n = int(f.get("frame", 0))
        if v and spans and prev is not None and n == prev + 1 and spans[-1][1] == prev:
            spans[-1] = (spans[-1][0], n, spans[-1][2])
        elif v:
            spans.append((n, n, describe(v)))
        prev = n
    return spans


def perception_fault_spans(frames: list[dict[str, Any]]) -> list[tuple[int, int, str]]:
    """Runs of consecutive frames with a perception fault: (first frame, last frame, first message)."""
    return _frame_spans(frames, "perception", str)


def _describe_cameras(c: dict[str, Any]) -> str:
    what = []
    if c.get("gain_triggered"):
        what.append(f"gain/tone: grey-level shift {float(c.get('grey_shift', 0.0)):.1f} levels")
    if c.get("noise_equalised"):
        what.append(f"noise: excess {float(c.get('noise_excess', 0.0)):.2f} grey levels")
    return "; ".join(what) or "mismatched"


def camera_mismatch_spans(frames: list[dict[str, Any]]) -> list[tuple[int, int, str]]:
    """Runs of consecutive frames with a ``cameras`` entry (the pair read as mismatched): (first frame, last frame,
    what the first frame's checks read)."""
    return _frame_spans(frames, "cameras", _describe_cameras)


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.3f}"
    return str(v)


def _thumb_png(fig) -> str:
    return figure_data_uri(fig, dpi=55, tight=True)


def _run_dirs(record_dir: Path) -> list[Path]:
    return sorted(p.parent for p in Path(record_dir).glob("*/run.json"))


def expand_run_dirs(paths: list[Path]) -> list[Path]:
    """Run record directories as given, or the runs of a suite's record directory (its */run.json);
    FatalError naming a path that is neither."""
    out: list[Path] = []
    for d in map(Path, paths):
        if (d / "run.json").is_file():
            out.append(d)
            continue
        inner = _run_dirs(d)
        if not inner:
            raise FatalError(f"{d}: no run record (run.json) in it or in its subdirectories "
                             "(record with `fuzzystereo sim suite --record DIR` or `run --record DIR`)")
        out.extend(inner)
    return out


def _contact_text(run_dir: Path) -> str:
    """The contact class of a run record and the bearing of the obstacle hit ('' without a contact or
    without the simulated truth)."""
    from .contacts import trace_contact

    try:
        c = trace_contact(run_dir)
    except FatalError:
        return ""
    if c is None:
        return ""
    b = c.get("bearing_deg")
    return c["class"] + ("" if b is None else f", {b:+.0f} deg")


def write_suite_report(record_dir: Path, out: Path, failures_only: bool = True) -> tuple[Path, int, int]:
    """One HTML page for a suite's run records (``fuzzystereo sim suite --record DIR``): a table of
    every run (status, time, path, clearance) and the trajectory plot of each failed run (of every
    run with failures_only = False), failures first. Returns (out, runs, failures)."""
    dirs = _run_dirs(record_dir)
    if not dirs:
        raise FatalError(f"{record_dir}: no run records (*/run.json; record with `fuzzystereo sim suite --record DIR`)")
    runs = []
    for d in dirs:
        run, frames = load_run(d)
        res = run.get("result", {})
        status = str(res.get("status", "reached" if res.get("reached") else "?"))
        # success: the goal where a path exists (finite shortest_m), a safe stop where none does (a
        # "blocked" stop in a solvable scenario is a failure)
        shortest = res.get("shortest_m")
        solvable = isinstance(shortest, (int, float)) and math.isfinite(shortest)
        ok = bool(res.get("reached")) if solvable else bool(res.get("safe_stop"))
        runs.append((ok, d.name, status, run, frames, _contact_text(d)))
    runs.sort(key=lambda r: (r[0], r[1]))
    failed = sum(1 for r in runs if not r[0])
    rows = []
    for ok, name, status, run, _, contact in runs:
        res = run.get("result", {})
        colour = "" if ok else " style='color:#b00'"
        rows.append(
            f"<tr{colour}><td><a href='#{html.escape(name)}'>{html.escape(name)}</a></td><td>{html.escape(status)}</td>"
            f"<td>{_fmt(res.get('time_s', ''))}</td><td>{_fmt(res.get('path_m', ''))}</td>"
            f"<td>{_fmt(res.get('shortest_m', ''))}</td><td>{_fmt(res.get('min_clearance_m', ''))}</td>"
            f"<td>{html.escape(contact)}</td></tr>")
    figs = []
    for ok, name, status, run, frames, contact in runs:
        if ok and failures_only:
            continue
        caption = f"{name}: {status}" + (f" ({contact})" if contact else "")
        figs.append(f"<figure id='{html.escape(name)}'><img src='{_thumb_png(trajectory_figure(run, frames))}'>"
                    f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    parts = [
        "<!doctype html><meta charset='utf-8'><title>fuzzystereo suite</title>",
        "<style>body{font-family:sans-serif;max-width:1200px;margin:auto}td,th{padding:2px 8px;text-align:left}"
        "figure{display:inline-block;margin:6px;vertical-align:top}img{max-width:380px}</style>",
        f"<h1>fuzzystereo suite — {html.escape(str(record_dir))}</h1>",
        f"<p>{len(runs)} runs, {failed} failed (collision, struck, timeout, or no safe stop where no path exists)</p>",
        "<table><tr><th>run</th><th>status</th><th>time s</th><th>path m</th><th>shortest m</th><th>min clearance m</th><th>contact (fuzzyctl contacts)</th></tr>"
        + "".join(rows) + "</table>",
        "<h2>" + ("Failed runs" if failures_only else "All runs") + "</h2>" + ("".join(figs) or "<p>none</p>"),
    ]
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(parts))
    return out, len(runs), failed
