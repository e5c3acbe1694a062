"""The ``fuzzyctl`` command line (click). Thin: parse options, call one library function, print.

Every user or device fault is a :class:`~fuzzyctl.errors.FatalError`, caught once in :func:`main`
and printed as one line (exit code 2); ``--verbose`` adds the traceback.
"""

from __future__ import annotations

import sys
import traceback
from pathlib import Path

import click
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from . import __version__
from .errors import FatalError

# Rich wraps at 80 columns when not on a terminal (pipes, CI logs); tables of metric names need more.
_WIDTH = None if sys.stdout.isatty() else 120
console = Console(highlight=False, width=_WIDTH)
err_console = Console(stderr=True, highlight=False, width=_WIDTH)


class _State:
    verbose = False


state = _State()

_path = click.Path(path_type=Path)
_existing_file = click.Path(path_type=Path, exists=True, dir_okay=False)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("-v", "--verbose", is_flag=True, help="Show tracebacks for errors.")
@click.version_option(__version__, prog_name="fuzzyctl")
def app(verbose: bool) -> None:
    """Host tools for fuzzystereo: FIS checks, the float64 desktop reference, firmware comparison."""
    state.verbose = verbose


# ---- fis ------------------------------------------------------------------------------------


@app.group("fis", short_help="The fuzzy inference system (eq. 10-12, Table I).")
def fis_group() -> None:
    """The fuzzy inference system (eq. 10-12, Table I)."""


_fis_option = click.option(
    "--fis", "fis_file", type=_existing_file, default=None, help="FIS definition (default common/fis/fis.toml)."
)


@fis_group.command("plot")
@click.option("--out", type=_path, required=True, help="Directory for the PNG files.")
@_fis_option
@click.option("--points", type=click.IntRange(5, 1001), default=101, show_default=True, help="Surface grid size per axis.")
def fis_plot(out: Path, fis_file: Path | None, points: int) -> None:
    """Membership functions of dc1, dc2 and the output, and the FIS surface, as PNG."""
    from .fis import Fis, load_definition
    from .plots import write_fis_plots

    fis = Fis(load_definition(fis_file))
    for path in write_fis_plots(fis, out, surface_points=points):
        console.print(f"wrote {path}")


@fis_group.command("show")
@_fis_option
def fis_show(fis_file: Path | None) -> None:
    """Validate the FIS definition and print Table I."""
    from .fis import load_definition

    d = load_definition(fis_file)
    table = Table(title=f"{d.name} (v{d.version}) — {d.source}")
    for col in ("rule", "dc1", "dc2", d.output.name):
        table.add_column(col)
    for r in d.rules:
        table.add_row(str(r.number), r.dc1, r.dc2, r.out)
    console.print(table)
    console.print(
        f"terms: dc1 {len(d.dc1.terms)}, dc2 {len(d.dc2.terms)}, output {len(d.output.terms)}; "
        f"universe: {d.input_points} input / {d.output_points} output samples"
    )


@fis_group.command("eval")
@click.argument("dc1", type=click.FloatRange(0.0, 1.0))
@click.argument("dc2", type=click.FloatRange(0.0, 1.0))
@_fis_option
def fis_eval_cmd(dc1: float, dc2: float, fis_file: Path | None) -> None:
    """FIS output for one pair (DC1 DC2 in [0, 1]) by scikit-fuzzy's ControlSystemSimulation."""
    from .fis import Fis, load_definition

    console.print(f"{Fis(load_definition(fis_file)).evaluate(dc1, dc2):.9f}")


@fis_group.command("check")
@click.option("--points", type=click.IntRange(1), default=1000, show_default=True, help="Random input pairs (corners, edges and term centres are added).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the random pairs.")
@click.option("--bin", "binary", type=_path, default=None, help="fuzzystereo binary (default $FUZZYSTEREO_BIN or build/default/fuzzystereo).")
@_fis_option
@click.option("--config", "config_file", type=_existing_file, default=None, help="Config passed to the firmware (fis.lut_size).")
@click.option("--tolerance", type=click.FloatRange(0.0), default=0.01, show_default=True, help="Max |LUT - scikit-fuzzy| (1 % of the output range).")
def fis_check(points: int, seed: int, binary: Path | None, fis_file: Path | None, config_file: Path | None, tolerance: float) -> None:
    """Firmware `fis eval` (LUT and exact) against scikit-fuzzy; non-zero exit above tolerance."""
    from .firmware import find_binary
    from .fischeck import EXACT_TOLERANCE, check_firmware_fis

    exe = find_binary(binary)
    res = check_firmware_fis(exe, n_random=points, seed=seed, fis_path=fis_file, config_path=config_file)
    table = Table(title=f"firmware FIS vs scikit-fuzzy ({len(res.dc1)} pairs, seed {seed})")
    for col in ("firmware output", "max |error|", "mean |error|", "worst at (dc1, dc2)", "tolerance"):
        table.add_column(col)
    rows = (("LUT (fixed point)", res.lut_error, tolerance), ("exact (double)", res.exact_error, EXACT_TOLERANCE))
    for name, err, tol in rows:
        worst, a, b = res.worst(err)
        table.add_row(name, f"{worst:.3g}", f"{err.mean():.3g}", f"({a:.4f}, {b:.4f})", f"{tol:g}")
    console.print(table)
    lut_max = float(res.lut_error.max())
    if lut_max > tolerance:
        from .errors import CheckFailed

        raise CheckFailed(f"FIS LUT max abs error {lut_max:.4g} exceeds {tolerance:g}")
    console.print(f"max abs error (LUT) {lut_max:.4g} <= {tolerance:g}: OK")


# ---- config ---------------------------------------------------------------------------------


@app.group("config", short_help="Matcher configuration: validate, show, schema.")
def config_group() -> None:
    """Matcher configuration (common/config/schema.toml)."""


@config_group.command("check")
@click.argument("path", type=_path)
def config_check(path: Path) -> None:
    """Validate a config file against the schema (defaults fill missing fields)."""
    from .config import load_config

    load_config(path)
    console.print(f"{path}: OK")


@config_group.command("show")
@click.argument("path", type=_path, required=False)
def config_show(path: Path | None) -> None:
    """Print the resolved config (defaults overlaid with PATH) as TOML."""
    from .config import load_config

    click.echo(load_config(path).to_toml(), nl=False)


@config_group.command("schema")
def config_schema() -> None:
    """Every config field with its default, valid range and meaning."""
    from .config import default_values, load_schema

    schema = load_schema()
    defaults = default_values(schema)
    table = Table(title="config fields (common/config/schema.toml)")
    for col in ("field", "default", "valid", "meaning"):
        table.add_column(col)
    for section, fields in schema.items():
        for name, spec in fields.items():
            table.add_row(spec.key, str(defaults[section][name]), spec.range_text(), spec.doc)
    console.print(table)


# ---- serial link (fuzzyctl --port PORT ...): fuzzyctl/link/cli.py ----------------------------

from .link.cli import register as _register_link  # noqa: E402

_register_link(app, config_group, console)


# ---- reference ------------------------------------------------------------------------------


@app.group("reference", short_help="The float64 desktop reference of the matcher.")
def reference_group() -> None:
    """The float64 desktop reference of the matcher (the firmware's oracle)."""


_engine_option = click.option(
    "--fis-engine", "engine", type=click.Choice(["fast", "skfuzzy"]), default="fast", show_default=True,
    help="fast: vectorised twin of scikit-fuzzy's arithmetic, cross-checked against ControlSystemSimulation "
    "on samples; skfuzzy: ControlSystemSimulation for every distinct pair (slow).",
)


@reference_group.command("detect")
@click.option("--dump", "dump_dir", type=_path, required=True, help="A detect dump (fuzzystereo detect --dump: OUT or OUT/dump).")
@click.option("--out", type=_path, required=True, help="Output directory for the reference's masks and obstacles.json.")
def reference_detect(dump_dir: Path, out: Path) -> None:
    """Float64 obstacle detection (eq. 16-25) on a firmware detect dump's inputs and config."""
    from .detect_compare import find_detect_dump, run_reference_on_dump, write_reference_outputs

    d = find_detect_dump(dump_dir)
    if d is None:
        raise FatalError(f"no detect dump in {dump_dir} (run `fuzzystereo detect ... --dump`)")
    _, r = run_reference_on_dump(d)
    write_reference_outputs(out, r)
    console.print(f"reference: road {'found' if r.road_found else 'not found'}, {len(r.obstacles)} obstacles; wrote {out}")
    for o in r.obstacles:
        console.print(f"  #{o.id} {o.cls:4s} Z {o.distance_m:.2f} m  box {o.box}  {o.pixel_count} px")


@reference_group.command("match")
@click.option("--left", "left_path", type=_path, required=True, help="Left image.")
@click.option("--right", "right_path", type=_path, required=True, help="Right image.")
@click.option("--config", "config_file", type=_path, default=None, help="TOML config (defaults: common/config/default.toml).")
@click.option("--labels-from", type=_path, default=None, help="Reuse labels_left/right.npy from this firmware dump directory.")
@_fis_option
@_engine_option
@click.option("--out", type=_path, required=True, help="Output directory (OUT/dump/ in the firmware's dump format).")
def reference_match(left_path: Path, right_path: Path, config_file: Path | None, labels_from: Path | None,
                    fis_file: Path | None, engine: str, out: Path) -> None:
    """Match one rectified pair with the float64 reference; write the stage dump."""
    from . import dump as dumpmod
    from .config import load_config
    from .fis import Fis, load_definition
    from .reference import match
    from .reference.image import load_grey

    cfg = load_config(config_file)
    fis = Fis(load_definition(fis_file))
    left, right = load_grey(left_path), load_grey(right_path)
    if left.shape != right.shape:
        raise FatalError(f"left {left_path} is {left.shape[1]}x{left.shape[0]} but right {right_path} is "
                         f"{right.shape[1]}x{right.shape[0]}; a rectified pair must match")
    labels = dumpmod.read_labels(labels_from) if labels_from is not None else (None, None)
    with console.status("running the reference ..."):
        r = match(left, right, cfg, fis, labels[0], labels[1], engine=engine)
    _write_reference_outputs(out, r, cfg, fis, left_path, right_path, engine)
    console.print(
        f"reference: {left.shape[1]}x{left.shape[0]}, D={cfg.cost.max_disparity}, "
        f"{r.labels_left.max() + 1} + {r.labels_right.max() + 1} segments"
        f"{' (labels from ' + str(labels_from) + ')' if labels_from else ''}"
    )
    console.print("  stage ms: " + " ".join(f"{k} {v:.0f}" for k, v in r.timings_ms.items()))
    console.print(f"  wrote {out}/dump/, disp_left.png, disp_right.png, disp_left_color.png")


def _write_reference_outputs(out: Path, r, cfg, fis, left_path, right_path, engine: str) -> None:
    import cv2
    import numpy as np

    from . import dump as dumpmod
    from .report import colour_disparity

    out.mkdir(parents=True, exist_ok=True)
    dumpmod.write_dump(out / "dump", r, {
        "firmware_version": f"fuzzyctl-reference {__version__}",
        "producer": "fuzzyctl reference",
        "left": str(left_path), "right": str(right_path),
        "config_toml": cfg.to_toml(), "fis_name": fis.defn.name, "fis_engine": engine,
    })
    for name, disp in (("disp_left", r.disp_final), ("disp_right", r.disp_right_wta)):
        # KITTI convention: uint16, disparity * 256, 0 = no estimate
        kitti = np.where(np.isnan(disp), 0, np.clip(np.floor(np.nan_to_num(disp) * 256 + 0.5), 1, 65535))
        cv2.imwrite(str(out / f"{name}.png"), kitti.astype(np.uint16))
        cv2.imwrite(str(out / f"{name}_color.png"), colour_disparity(disp, cfg.cost.max_disparity))


_jobs_option = click.option("--jobs", "-j", type=click.IntRange(1), default=1, show_default=True,
                            help="Frames processed in parallel (worker processes).")
_limit_option = click.option("--limit", type=click.IntRange(0), default=0, show_default=True,
                             help="At most N frames per set (0 = all), as `fuzzystereo eval --limit`.")
_bin_option = click.option("--bin", "binary", type=_path, default=None,
                           help="fuzzystereo binary (default $FUZZYSTEREO_BIN or build/default/fuzzystereo).")


def _frames(dataset_dir: Path, limit: int):
    from .dataset import discover, select

    skipped: list[str] = []
    frames = select(discover(dataset_dir), limit, need_gt=True, skipped=skipped)
    for s in skipped:
        err_console.print(f"skipping {s}")
    if not frames:
        raise FatalError(f"no frames with ground truth under '{dataset_dir}'")
    return frames


@reference_group.command("eval")
@click.option("--dataset", "dataset_dir", type=_path, required=True,
              help="Datasets root, one set's folder or one scene folder (the layouts of `fuzzystereo eval`).")
@click.option("--from-firmware", is_flag=True,
              help="Score the firmware's final maps (`fuzzystereo match --dump` per frame) instead of the reference's.")
@click.option("--runs", "runs_dir", type=_path, default=None,
              help="With --from-firmware: keep the firmware runs in RUNS/<set>/<name>/ and reuse those already there.")
@click.option("--firmware-json", type=_existing_file, default=None,
              help="`fuzzystereo eval --json` output to put beside these figures (with --from-firmware: must agree).")
@click.option("--config", "config_file", type=_existing_file, default=None, help="Matcher config TOML (search range per layout).")
@_limit_option
@click.option("--json", "json_out", type=_path, default=None, help="Write the figures as {\"sets\": {SET: {METHOD: {...}}}}.")
@click.option("--tolerance", type=click.FloatRange(0.0), default=1e-6, show_default=True,
              help="Max |difference| to the --firmware-json figures when scoring the firmware's maps.")
@_jobs_option
@_bin_option
@_fis_option
@_engine_option
def reference_eval(dataset_dir: Path, from_firmware: bool, runs_dir: Path | None, firmware_json: Path | None,
                   config_file: Path | None, limit: int, json_out: Path | None, tolerance: float, jobs: int,
                   binary: Path | None, fis_file: Path | None, engine: str) -> None:
    """KITTI-devkit figures (avg_err, bad2, bad3, d1, density) per set, as `fuzzystereo eval` computes them."""
    import json

    from .config import load_config
    from .errors import CheckFailed
    from .evaluate import METHOD, diff_figures, read_eval_json, scorer, summarise
    from .firmware import find_binary
    from .parallel import run_frames

    load_config(config_file)  # a bad config fails before the first frame
    theirs = read_eval_json(firmware_json) if firmware_json is not None else None
    frames = _frames(dataset_dir, limit)
    source = "firmware" if from_firmware else "reference"
    kwargs = dict(config_path=config_file, fis_path=fis_file, engine=engine)
    if from_firmware:
        kwargs.update(binary=find_binary(binary), runs_root=runs_dir, threads=1 if jobs > 1 else None)
    scores, errors = [], []
    for frame, res in run_frames(scorer(source, **kwargs), frames, jobs, f"eval ({source})", err_console):
        if isinstance(res, FatalError):
            errors.append(f"{frame.key}: {res}")
            continue
        scores.append(res)
        m = res.metrics
        err_console.print(f"{frame.key} D={frame.max_disparity}: avg_err {m.avg_err:.3f} bad2 {m.bad2:.2f}% "
                          f"bad3 {m.bad3:.2f}% d1 {m.d1:.2f}% density {m.density:.1f}%")
    if errors:
        raise FatalError("; ".join(errors))
    method = METHOD[source]
    ours = summarise(scores, method)
    table = Table(title=f"{method} on {dataset_dir} (per-frame means, KITTI hole filling)")
    for col in ("set", "method", "frames", "avg_err", "bad2%", "bad3%", "d1%", "density%"):
        table.add_column(col, justify="left" if col in ("set", "method") else "right")
    for set_name, methods in ours["sets"].items():
        f = methods[method]
        table.add_row(set_name, method, str(f["frames"]), f"{f['avg_err']:.3f}", f"{f['bad2']:.2f}", f"{f['bad3']:.2f}",
                      f"{f['d1']:.2f}", f"{f['density']:.2f}")
    console.print(table)
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(ours, indent=2) + "\n", encoding="utf-8")
        console.print(f"wrote {json_out}")
    if theirs is None:
        return
    diffs = diff_figures(ours, theirs, method)
    table = Table(title=f"vs firmware eval {firmware_json}")
    for col in ("set", "figure", method, "fuzzystereo eval", "|diff|"):
        table.add_column(col)
    for d in diffs:
        table.add_row(d.set, d.figure, f"{d.ours:.6f}", "missing" if d.theirs is None else f"{d.theirs:.6f}",
                      "" if d.abs_diff is None else f"{d.abs_diff:.2e}")
    console.print(table)
    if from_firmware:
        bad = [d for d in diffs if d.abs_diff is None or d.abs_diff > tolerance]
        if bad:
            raise CheckFailed("metric code disagrees with the firmware eval: " + ", ".join(
                f"{d.set} {d.figure} {d.ours:.6g} vs {d.theirs}" for d in bad))
        console.print(f"every figure within {tolerance:g} of the firmware eval: OK")


# ---- compare --------------------------------------------------------------------------------


@app.command("compare")
@click.argument("run_dir", type=_path, required=False)
@click.option("--dataset", "dataset_dir", type=_path, default=None,
              help="Instead of RUN_DIR: run the firmware on every frame under DIR and compare each.")
@click.option("--tolerances", type=_path, default=None, help="Tolerances TOML (default common/compare/tolerances.toml).")
@click.option("--report", type=_path, default=None,
              help="HTML report file; with --dataset a directory (runs, report.html per frame, index.html, summary.json).")
@click.option("--reference-out", type=_path, default=None, help="Also write the reference's outputs (dump format) here.")
@click.option("--own-segmentation", is_flag=True, help="Let the reference run its own SLIC instead of reusing the firmware's labels.")
@_jobs_option
@_limit_option
@click.option("--config", "config_file", type=_existing_file, default=None, help="With --dataset: config passed to the firmware.")
@_bin_option
@_fis_option
@_engine_option
def compare_cmd(run_dir: Path | None, dataset_dir: Path | None, tolerances: Path | None, report: Path | None,
                reference_out: Path | None, own_segmentation: bool, jobs: int, limit: int, config_file: Path | None,
                binary: Path | None, fis_file: Path | None, engine: str) -> None:
    """Firmware dump (RUN_DIR/dump or RUN_DIR) vs the float64 reference, stage by stage; or, with
    --dataset, every frame of a dataset (the firmware run with the layout's search range)."""
    from .compare import compare_run
    from .errors import CheckFailed

    if (run_dir is None) == (dataset_dir is None):
        raise FatalError("give either RUN_DIR (one firmware dump) or --dataset DIR (run the firmware on every frame)")
    if dataset_dir is not None:
        if reference_out is not None or own_segmentation:
            raise FatalError("--reference-out and --own-segmentation apply to one RUN_DIR, not to --dataset")
        _compare_dataset(dataset_dir, tolerances, report, jobs, limit, config_file, binary, fis_file, engine)
        return

    from .detect_compare import find_detect_dump

    if find_detect_dump(run_dir) is not None:  # a `fuzzystereo detect --dump` run
        _compare_detect(run_dir, tolerances)
        return
    with console.status("running the reference on the dump ..."):
        c = compare_run(run_dir, tolerances, fis_file, engine=engine, own_segmentation=own_segmentation)
    table = Table(title=f"firmware vs reference — {c.dump.path}")
    table.add_column("stage", no_wrap=True, min_width=12)
    table.add_column("metric", no_wrap=True, min_width=36)
    for col in ("value", "tolerance", "status"):
        table.add_column(col, no_wrap=True)
    failing = _fill_metrics_table(table, c)
    console.print(table)
    if c.ignored_config:
        console.print("firmware config keys not modelled by the reference: "
                      + ", ".join(f"{k} = {v!r}" for k, v in c.ignored_config.items()))
    if reference_out is not None:
        _write_reference_outputs(reference_out, c.reference, c.config, c.fis, c.dump.path / "left.png",
                                 c.dump.path / "right.png", engine)
        console.print(f"wrote the reference outputs to {reference_out}")
    if report is not None:
        from .report import write_report

        console.print(f"wrote {write_report(c, report)}")
    if failing:
        raise CheckFailed("comparison outside tolerance: " + ", ".join(
            f"{m.name} = {m.value:.4g} (needs {t.text()})" for m, t in c.failures()))
    console.print("all checked metrics within tolerance")


def _fill_metrics_table(table: Table, c) -> set[str]:
    """One row per compared metric (value, tolerance, ok/FAIL); returns the failing names."""
    failing = {m.name for m, _ in c.failures()}
    for m in c.metrics:
        tol = c.tolerances.get(m.name)
        value = "n/a" if m.value is None else (f"{m.value:.3f} %" if m.unit == "%" else f"{m.value:.4g}")
        status = "" if tol is None else ("n/a" if m.value is None else "[red]FAIL[/]" if m.name in failing else "[green]ok[/]")
        table.add_row(m.stage, m.name, value, tol.text() if tol else "", status)
    return failing


def _compare_detect(run_dir: Path, tolerances: Path | None) -> None:
    from .detect_compare import compare_detect
    from .errors import CheckFailed

    with console.status("running the detection reference on the dump ..."):
        c = compare_detect(run_dir, tolerances)
    table = Table(title=f"firmware vs reference (detection) — {c.dump_dir}")
    for col in ("stage", "metric", "value", "tolerance", "status"):
        table.add_column(col, no_wrap=True)
    failing = _fill_metrics_table(table, c)
    console.print(table)
    if failing:
        raise CheckFailed("comparison outside tolerance: " + ", ".join(
            f"{m.name} = {m.value:.4g} (needs {t.text()})" for m, t in c.failures()))
    console.print("all checked metrics within tolerance")


def _compare_dataset(dataset_dir: Path, tolerances: Path | None, report: Path | None, jobs: int, limit: int,
                     config_file: Path | None, binary: Path | None, fis_file: Path | None, engine: str) -> None:
    import json

    from .compare import load_tolerances
    from .dataset_compare import comparer, pct, pooled
    from .errors import CheckFailed
    from .firmware import find_binary
    from .parallel import run_frames

    load_tolerances(tolerances)  # bad tolerances fail before the first frame
    exe = find_binary(binary)
    frames = _frames(dataset_dir, limit)
    fn = comparer(exe, runs_root=report, tolerances=tolerances, fis_path=fis_file, engine=engine,
                  config_path=config_file, threads=1 if jobs > 1 else None, report=report is not None)
    summaries, errors = [], {}
    for frame, res in run_frames(fn, frames, jobs, f"compare ({len(frames)} frames, {jobs} jobs)", err_console):
        if isinstance(res, FatalError):
            errors[frame.key] = str(res)
            err_console.print(f"[red]{escape(frame.key)}: {escape(str(res))}[/]")
            continue
        summaries.append(res)
        verdict = "[green]ok[/]" if res.passed else "[red]FAIL[/]"
        err_console.print(f"{frame.key}: winners {res.winner_pct:.2f} %, final within 1 px {res.valid_within_1px_pct:.2f} % "
                          f"of valid pixels, {res.seconds:.0f} s {verdict}")
    summaries.sort(key=lambda s: (s.frame.set, s.frame.name))
    table = Table(title=f"firmware vs reference, firmware labels — {dataset_dir}")
    for col in ("frame", "D", "segs", "win L%", "win R%", "win%", "±1px valid%", "±1px all%", "s", "status"):
        table.add_column(col, no_wrap=True, justify="left" if col in ("frame", "status") else "right")
    for s in summaries:
        status = "[green]ok[/]" if s.passed else "[red]FAIL[/]"
        table.add_row(s.frame.key, str(s.frame.max_disparity), str(s.segments), f"{s.winner_left_pct:.2f}",
                      f"{s.winner_right_pct:.2f}", f"{s.winner_pct:.2f}", f"{s.valid_within_1px_pct:.2f}",
                      f"{s.final_within_1px_pct:.2f}", f"{s.seconds:.0f}", status)
    win, within = pooled(summaries)
    table.add_row("[bold]overall[/]", "", str(sum(s.segments for s in summaries)), "", "", f"[bold]{win:.2f}[/]",
                  f"[bold]{within:.2f}[/]", "", "", f"{sum(s.passed for s in summaries)}/{len(frames)} ok")
    table.caption = ("win: segments with the reference's winner; ±1px valid: of the pixels valid in either final map, "
                     "both valid and within 1 px; ±1px all: of all pixels, both invalid counting as agreement")
    console.print(table)
    for s in summaries:
        if s.failures:
            console.print(f"{s.frame.key}: " + ", ".join(s.failures))
    if report is not None:
        from .report import write_index

        doc = {
            "dataset": str(dataset_dir), "frames": len(frames),
            "overall": {"winner_agreement_pct": win, "final_within_1px_valid_pct": within,
                        "final_within_1px_both_valid_pct": pct(sum(s.both_valid_within_1px for s in summaries),
                                                               sum(s.both_valid for s in summaries)),
                        "final_within_1px_firmware_valid_pct": pct(sum(s.firmware_valid_within_1px for s in summaries),
                                                                   sum(s.firmware_valid for s in summaries))},
            "per_frame": {s.frame.key: {
                "winner_left_pct": s.winner_left_pct, "winner_right_pct": s.winner_right_pct,
                "winner_pct": s.winner_pct, "final_within_1px_valid_pct": s.valid_within_1px_pct,
                "final_within_1px_pct": s.final_within_1px_pct, "segments": s.segments,
                "final_within_1px_both_valid_pct": pct(s.both_valid_within_1px, s.both_valid),
                "final_within_1px_firmware_valid_pct": pct(s.firmware_valid_within_1px, s.firmware_valid),
                "seconds": s.seconds, "failures": s.failures} for s in summaries},
            "errors": errors,
        }
        report.mkdir(parents=True, exist_ok=True)
        (report / "summary.json").write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
        console.print(f"wrote {write_index(summaries, report, str(dataset_dir))} and {report / 'summary.json'}")
    failed = [s.frame.key for s in summaries if not s.passed] + list(errors)
    if failed:
        raise CheckFailed(f"{len(failed)} of {len(frames)} frames outside tolerance or failed: {', '.join(failed)}")
    console.print(f"all {len(frames)} frames within tolerance")


# ---- run report -------------------------------------------------------------------------------


@app.command("calibrate", short_help="Stereo calibration file from chessboard pairs (OpenCV calib3d).")
@click.argument("folder", type=click.Path(path_type=Path, file_okay=False, exists=True))
@click.option("--board", required=True, help="Chessboard INNER corners, COLSxROWS, e.g. 9x6 (unequal sides).")
@click.option("--square", "square_m", type=float, required=True, help="Square side in METRES, e.g. 0.025.")
@click.option("--out", type=_path, required=True, help="Calibration file to write (YAML, docs/capture.md).")
@click.option("--min-pairs", type=click.IntRange(3, 1000), default=8, show_default=True,
              help="Pairs with the board found in both views needed.")
@click.option("--max-view-error", type=click.FloatRange(min=0.05), default=None,
              help="While a view's reprojection error exceeds this [px], drop the worst view and calibrate again.")
@click.option("--height-m", type=click.FloatRange(min=0.0, max=5.0), default=None,
              help="Optical centre above the ground [m], written for the detector.")
@click.option("--pitch-deg", type=click.FloatRange(min=-45.0, max=45.0), default=None,
              help="Downward camera tilt [deg], written for the detector.")
@click.option("--preview", type=_path, default=None, help="PNG of one pair rectified with the result, with row lines.")
@click.option("--report", type=_path, default=None,
              help="HTML page: figures, per-view errors, corner coverage, a rectified pair.")
@click.option("--max-epipolar", type=click.FloatRange(min=0.0), default=1.0, show_default=True,
              help="Fail (exit 1, file still written) when the rectified epipolar RMS error exceeds this [px].")
def calibrate_cmd(folder: Path, board: str, square_m: float, out: Path, min_pairs: int, max_view_error: float | None,
                  height_m: float | None, pitch_deg: float | None, preview: Path | None, report: Path | None,
                  max_epipolar: float) -> None:
    """Calibrate a stereo pair from a `fuzzystereo capture` folder of raw chessboard pairs
    (FOLDER/left/*, FOLDER/right/*) and write the calibration file `camera.calibration` reads."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    from .calibrate import (calibrate_folder, find_pairs, pair_by_name, parse_board, summary_lines, write_calibration,
                            write_preview, write_report)
    from .errors import CheckFailed

    b = parse_board(board, square_m)
    n = len(find_pairs(folder))
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[last]}"),
                  console=err_console, transient=True) as progress:
        task = progress.add_task("corners", total=n, last="")
        cal = calibrate_folder(folder, b, min_pairs=min_pairs, max_view_error=max_view_error,
                               progress=lambda name: progress.update(task, advance=1, last=name))
    for name, reason in cal.skipped:
        console.print(f"skipped {name}: {reason}")
    if cal.dropped:
        console.print(f"dropped (error > {max_view_error} px): {', '.join(cal.dropped)}")
    worst = sorted(cal.views, key=lambda v: -max(v.left_px, v.right_px))[:3]
    console.print("worst views: " + ", ".join(f"{v.name} {v.left_px:.2f}/{v.right_px:.2f} px" for v in worst))
    for line in summary_lines(cal):
        console.print(line)
    write_calibration(out, cal, height_m=height_m, pitch_deg=pitch_deg)
    console.print(f"wrote {out}")
    first = pair_by_name(folder, cal.views[0].name)
    if preview is not None:
        write_preview(preview, cal, first)
        console.print(f"wrote {preview}")
    if report is not None:
        write_report(report, cal, first)
        console.print(f"wrote {report}")
    if cal.epipolar_rms_px > max_epipolar:
        raise CheckFailed(
            f"rectified epipolar error {cal.epipolar_rms_px:.3f} px RMS > --max-epipolar {max_epipolar} px: the matcher "
            "searches along rows and will miss; re-take the pairs (sharp, still, board filling the view, many tilts)"
        )


@app.command("rectcheck", short_help="Is a rectified rig still row-aligned? Feature row differences, no chessboard.")
@click.argument("folder", type=click.Path(path_type=Path, file_okay=False, exists=True), required=False)
@click.option("--left", "left_path", type=_existing_file, default=None, help="One rectified left image (with --right).")
@click.option("--right", "right_path", type=_existing_file, default=None, help="One rectified right image.")
@click.option("--max-disparity", type=click.FloatRange(min=1.0), default=256.0, show_default=True,
              help="Matches with a larger disparity are wrong matches.")
@click.option("--limit", type=click.IntRange(min=0), default=20, show_default=True,
              help="Pairs used, spread over the folder (0 = all).")
@click.option("--max-dy", type=click.FloatRange(min=0.0), default=0.5, show_default=True,
              help="Fail (exit 1) when the median |y_left - y_right| exceeds this [px].")
@click.option("--config", "config_file", type=_existing_file, default=None,
              help="Matcher config whose camera-difference thresholds the photometric check uses (default: the defaults).")
def rectcheck_cmd(folder: Path | None, left_path: Path | None, right_path: Path | None, max_disparity: float, limit: int,
                  max_dy: float, config_file: Path | None) -> None:
    """Row differences of SIFT matches in rectified pairs (a `fuzzystereo capture --calib` folder, or
    one pair): a stereo rig whose cameras moved since calibration shows a vertical offset, roll or
    scale trend. Exit 1 when the median |dy| exceeds --max-dy (then re-calibrate).

    Also reports whether the two cameras see the scene alike (brightness, tone, noise), as the matcher's
    own camera-difference checks read the pairs, with advice when most pairs read as mismatched."""
    from .calibrate import read_grey
    from .config import load_config
    from .errors import CheckFailed
    from .rectcheck import check_pairs, folder_pairs, photometric_check

    if (left_path is None) != (right_path is None) or (folder is None) == (left_path is None):
        raise FatalError("give a capture FOLDER, or --left and --right (one pair)")
    cfg = load_config(config_file)
    if folder is not None:
        pairs = folder_pairs(folder, limit=limit)
    else:
        pairs = [(left_path.name, read_grey(left_path), read_grey(right_path))]
    r = check_pairs(pairs, max_disparity=max_disparity)
    photo = photometric_check(pairs, cfg)
    for p, q in zip(r.pairs, photo.pairs):
        console.print(f"{p.name}: {p.matches} matches, |dy| median {p.median_abs_dy:.2f} px; grey shift {q.grey_shift:.1f}, "
                      f"noise {q.noise_left:.2f}/{q.noise_right:.2f}{' (mismatched)' if q.mismatched else ''}")
    for line in r.lines() + photo.lines():
        console.print(line)
    if (advice := photo.advice()) is not None:
        console.print(f"[yellow]warning:[/] {advice}")
    if r.median_abs_dy > max_dy:
        raise CheckFailed(
            f"median |dy| {r.median_abs_dy:.2f} px > --max-dy {max_dy} px: the rig is no longer rectified "
            "(re-calibrate: fuzzyctl calibrate, docs/capture.md)"
        )
    console.print(f"rectification OK (median |dy| <= {max_dy} px)")


@app.command("report", short_help="HTML report of a robot run record (fuzzystereo run --record DIR).")
@click.argument("run_dir", type=click.Path(path_type=Path, file_okay=False))
@click.option("--out", type=_path, default=None, help="HTML file (default RUN_DIR/report.html).")
@click.option("--frames", "max_frames", type=click.IntRange(2, 50), default=6, show_default=True, help="Annotated frames shown.")
def report_cmd(run_dir: Path, out: Path | None, max_frames: int) -> None:
    """Trajectory plot, annotated frames and stage timings of one run, as a single HTML file."""
    from .runreport import write_report

    path = write_report(run_dir, out or run_dir / "report.html", max_frames=max_frames)
    console.print(f"report: {path}")


@app.command("suite-report", short_help="HTML page of a suite's run records: every run, failures plotted.")
@click.argument("record_dir", type=click.Path(path_type=Path, file_okay=False))
@click.option("--out", type=_path, default=None, help="HTML file (default RECORD_DIR/suite.html).")
@click.option("--all", "all_runs", is_flag=True, help="Plot every run, not only the failed ones.")
def suite_report_cmd(record_dir: Path, out: Path | None, all_runs: bool) -> None:
    """Table of every run of `fuzzystereo sim suite --record RECORD_DIR` and the trajectory plot of each
    failed one (robot path, obstacles with their motion, tracks), failures first."""
    from .runreport import write_suite_report

    path, n, failed = write_suite_report(record_dir, out or record_dir / "suite.html", failures_only=not all_runs)
    console.print(f"suite report: {path} ({n} runs, {failed} failed)")


@app.command("detect-report", short_help="HTML page of a detect-eval result: misses classified, worst frames boxed.")
@click.argument("eval_json", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--dataset", type=click.Path(path_type=Path, file_okay=False), default=None,
              help="The generated set the evaluation ran on (default: the JSON's 'dataset').")
@click.option("--against", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="A base evaluation of the same set: gained / lost obstacles and FP changes per frame.")
@click.option("--out", type=_path, default=None, help="HTML file (default EVAL_JSON with .html).")
@click.option("--frames", "max_frames", type=click.IntRange(0, 10000), default=30, show_default=True,
              help="Frames pictured at most (changed ones first, then the worst).")
def detect_report_cmd(eval_json: Path, dataset: Path | None, against: Path | None, out: Path | None,
                      max_frames: int) -> None:
    """One HTML page of `fuzzystereo detect-eval --json EVAL_JSON`: the per-type table, every miss
    classified (none, merged, fragment, offset, distance), and the frames with misses or false positives
    drawn (ground truth white / yellow when missed, matched detections green, false positives red)."""
    from .detectreport import write_detect_report

    path, shown = write_detect_report(eval_json, out or eval_json.with_suffix(".html"), dataset, against, max_frames)
    console.print(f"detection report: {path} ({shown} frames pictured)")


def _write_json(path: Path | None, obj: object) -> None:
    """--json FILE of a report command: the figures as indented JSON (nothing when no file was asked for)."""
    if path is None:
        return
    import json as _json

    path.write_text(_json.dumps(obj, indent=2) + "\n")
    console.print(f"wrote {path}")


@app.command("track-errors", short_help="Tracker measurement and velocity errors of simulator run records.")
@click.argument("run_dirs", nargs=-1, required=True, type=click.Path(path_type=Path, file_okay=False))
@click.option("--min-hits", type=click.IntRange(1, 1000), default=4, show_default=True,
              help="Velocity error only of confirmed tracks with at least this many hits.")
@click.option("--json", "json_out", type=_path, default=None, help="Also write the tables as JSON.")
def track_errors_cmd(run_dirs: tuple[Path, ...], min_hits: int, json_out: Path | None) -> None:
    """Measurement error by bearing (signed outward / forward) and velocity error of moving and
    static obstacles' tracks, against the simulated world (fuzzystereo sim suite --record DIR)."""
    from rich.table import Table

    from .trackerrors import track_errors

    r = track_errors(list(run_dirs), min_hits=min_hits)
    fmt = lambda v: "-" if v is None else f"{v:+.3f}"  # noqa: E731
    t = Table(title=f"measurement error of updated tracks (m), {r['records']} records")
    for col in ("|bearing| deg", "n", "lateral (outward +)", "forward", "|error|"):
        t.add_column(col, justify="right")
    for row in r["measurement"]:
        lo, hi = row["bearing_deg"]
        t.add_row(f"{lo}-{hi}", str(row["n"]), fmt(row["lateral_outward_median_m"]), fmt(row["forward_median_m"]),
                  "-" if row["abs_median_m"] is None else f"{row['abs_median_m']:.3f}")
    console.print(t)
    v = Table(title=f"velocity error of confirmed tracks (hits >= {min_hits}), m/s")
    for col in ("obstacles", "n", "median", "p90"):
        v.add_column(col, justify="right")
    for kind, row in r["velocity"].items():
        v.add_row(kind, str(row["n"]), "-" if row["median_mps"] is None else f"{row['median_mps']:.3f}",
                  "-" if row["p90_mps"] is None else f"{row['p90_mps']:.3f}")
    console.print(v)
    m = r["movers"]
    if m["n"]:
        console.print(f"moving obstacles, {m['n']} track updates: position RMSE filtered {m['filt_pos_rmse_m']:.3f} m vs "
                      f"raw measurement {m['raw_pos_rmse_m']:.3f} m; velocity error from the 10th hit on "
                      f"({m['vel_after10_n']} updates): median {m['vel_after10_median_mps']:.3f}, "
                      f"RMS {m['vel_after10_rms_mps']:.3f}, p95 {m['vel_after10_p95_mps']:.3f} m/s")
    _write_json(json_out, r)


@app.command("track-replay", short_help="Re-run the tracker's Kalman filter on run records (reference; what-if settings).")
@click.argument("run_dirs", nargs=-1, required=True, type=click.Path(path_type=Path, file_okay=False))
@click.option("--set", "sets", multiple=True, metavar="tracker.KEY=VALUE",
              help="Filter setting instead of the record's (repeatable): accel_sigma_mps2, accel_sigma_steady_mps2, "
                   "maneuver_nis, maneuver_fade, init_vel_sigma_mps, velocity_measurement; or loop.meas_sigma_floor_m "
                   "(the floor of R, at or above the record's).")
@click.option("--json", "json_out", type=_path, default=None, help="Also write the figures as JSON.")
def track_replay_cmd(run_dirs: tuple[Path, ...], sets: tuple[str, ...], json_out: Path | None) -> None:
    """The float reference of the tracker's filter (paper eq. 26-32, host/src/fuzzyctl/reference/tracker.py)
    re-run on the measurements each record's tracks were updated with. Without --set the reference must
    reproduce the firmware's recorded states (agreement); with --set it shows what the filter would have
    estimated from the same measurements, with issue 5's tracking figures on simulator records."""
    from .trackreplay import parse_overrides, track_replay

    r = track_replay(list(run_dirs), parse_overrides(sets))
    a = r["agreement"]
    console.print(f"{r['records']} records, {a['states']} track states ({a['updates']} updates): reference vs firmware "
                  f"max |dp| {a['max_pos_diff_m']:.2e} m, max |dv| {a['max_vel_diff_mps']:.2e} m/s"
                  + (" (settings changed by --set: differences expected)" if r["overrides"] else ""))
    nis = r["nis"]
    if nis["n"]:
        console.print(f"filter consistency (no truth needed), {nis['n']} updates of tracks past their 3rd hit: position NIS "
                      f"mean {nis['mean']:.2f}, median {nis['median']:.2f}, {100 * nis['share_above_5_99']:.1f} % above 5.99 "
                      "(a consistent filter: mean 2, 5 %; larger: R too small for these measurements)")
    m = r["movers"]
    if m is not None and m["n"]:
        f = lambda v: "-" if v is None else f"{v:.3f}"  # noqa: E731
        console.print(f"moving obstacles, {m['n']} updates: position RMSE raw {f(m['raw_pos_rmse_m'])} m, firmware filter "
                      f"{f(m['firmware_pos_rmse_m'])} m, replayed filter {f(m['replay_pos_rmse_m'])} m; velocity error "
                      f"from the 10th hit ({m['vel_after10_n']} updates) p95 firmware {f(m['firmware_vel_after10_p95_mps'])}, "
                      f"replayed {f(m['replay_vel_after10_p95_mps'])} m/s")
    _write_json(json_out, r)


@app.command("give-up-replay", short_help="What [loop] give_up_after_s would have done on run records.")
@click.argument("run_dirs", nargs=-1, required=True, type=click.Path(path_type=Path, file_okay=False))
@click.option("--after", "afters", default="12,15,20", show_default=True, metavar="S[,S...]",
              help="give_up_after_s values to try [s], comma-separated.")
@click.option("--contact-margin", type=click.FloatRange(0.0), default=1.0, show_default=True,
              help="A contact counts as avoided only when the rule held this long before it [s].")
@click.option("--json", "json_out", type=_path, default=None, help="Also write the result as JSON.")
def give_up_replay_cmd(run_dirs: tuple[Path, ...], afters: str, contact_margin: float, json_out: Path | None) -> None:
    """The rule of [loop] give_up_after_s (stop for good after no progress with a blocked plan since the last
    progress; docs/robot.md "Session 44") on recorded runs (run directories, or a suite's record directory).
    The rule only ends runs, so the first frame where it holds, against how the run ended, is its effect:
    an arrival lost, a safe stop gained (a run without a free path that timed out), a contact avoided, or an
    earlier stop. Record with the rule off (give_up_after_s = 0)."""
    from .giveupreplay import EFFECTS, give_up_replay

    try:
        values = [float(v) for v in afters.split(",") if v.strip()]
    except ValueError:
        raise FatalError(f"--after: expected seconds separated by commas, e.g. 12,15,20 (got '{afters}')") from None
    r = give_up_replay(list(run_dirs), values, contact_margin)
    t = Table(title=f"give_up_after_s on {r['records']} recorded runs")
    t.add_column("after s", justify="right")
    for e in EFFECTS:
        t.add_column(e, justify="right")
    for row in r["afters"]:
        t.add_row(f"{row['after_s']:g}", *(str(row["counts"][e]) for e in EFFECTS))
    console.print(t)
    for row in r["afters"]:
        for c in row["changed"]:
            console.print(f"  {row['after_s']:g} s: {c['run']}: {c['status']} at {c['end_s']:.1f} s -> stop at "
                          f"{c['give_up_s']:.1f} s ({c['effect']})")
    _write_json(json_out, r)


def _planned(p: dict | None) -> str:
    """The contacts table's "planned" cell: frames of the last second with the obstacle in the planner's
    list / frames with the list recorded, and the kinds covering it at the last of them."""
    if p is None:
        return "-"
    return f"{p['covered']}/{p['frames']} {p['last_kinds'] or 'none'}"


@app.command("contacts", short_help="Trace the contacts of simulator run records: what was hit, what the robot knew.")
@click.argument("run_dirs", nargs=-1, required=True, type=click.Path(path_type=Path, file_okay=False))
@click.option("--json", "json_out", type=_path, default=None, help="Also write the contacts as JSON.")
def contacts_cmd(run_dirs: tuple[Path, ...], json_out: Path | None) -> None:
    """For each run that ended in a contact (`fuzzystereo sim suite --record DIR`; pass run
    directories or a suite's record directory): the obstacle hit, its bearing, whether the camera saw
    it, what the robot was doing, the last track near it, whether the planner had it in the last
    second ("planned": covered frames / frames with the planner's obstacles recorded, and the kinds
    covering it at the last; record with `--plan-every 1` to have every frame), the least share of the
    ground ahead the detector explained in the last second ("ground %", docs/robot.md "Session 32"),
    and a class (docs/robot.md "Session 29")."""
    from rich.table import Table

    from .contacts import contacts
    from .runreport import expand_run_dirs

    r = contacts(expand_run_dirs(list(run_dirs)))
    opt = lambda v, f: "-" if v is None else format(v, f)  # noqa: E731
    t = Table(title=f"contacts: {len(r['contacts'])} of {r['records']} records")
    for col in ("run", "t s", "class", "obst", "mover v", "bearing deg", "robot v, w", "seen s ago", "tracked s ago", "track",
                "planned", "ground %"):
        # the run's name is what one looks up next: never cut
        t.add_column(col, justify="right", no_wrap=col == "run",
                     min_width=max((len(c["run"]) for c in r["contacts"]), default=3) if col == "run" else None)
    for c in r["contacts"]:
        tr = c.get("track")
        t.add_row(c["run"], f"{c['time_s']:.1f}", c["class"], str(c.get("obstacle")),
                  opt(c.get("obstacle_speed_mps"), ".2f") if c.get("mover") else "static",
                  opt(c.get("bearing_deg"), "+.0f"), f"{c['robot_speed_mps']:.2f}, {c['robot_turn_radps']:+.2f}",
                  opt(c.get("seen_s_before"), ".1f"), opt(c.get("tracked_s_before"), ".1f"),
                  "-" if tr is None else f"#{tr['id']} {'C' if tr['confirmed'] else 'u'}{'M' if tr['mover'] else ''} "
                                         f"{tr['speed_mps']:.2f} m/s"
                                         + (f", {tr['moving_test']}" if tr.get("moving_test") else ""),
                  _planned(c.get("planned")),
                  opt(c.get("ground_ahead_min_pct"), ".0f"))
    console.print(t)
    console.print(", ".join(f"{k}: {v}" for k, v in r["classes"].items()))
    _write_json(json_out, r)


@app.command("verdicts", short_help="The loop's moving-test verdicts of simulator run records against the truth.")
@click.argument("run_dirs", nargs=-1, required=True, type=click.Path(path_type=Path, file_okay=False))
@click.option("--near", "near_m", type=click.FloatRange(0, None, min_open=True), default=2.0, show_default=True,
              help="Distance from the robot of the 'near' columns and of the coverage table [m].")
@click.option("--json", "json_out", type=_path, default=None, help="Also write the tables as JSON.")
@click.option("--features", "features_out", type=_path, default=None,
              help="Also write one CSV row per confirmed track-frame: the moving test's inputs, its verdict and the "
                   "truth (records since session 47).")
def verdicts_cmd(run_dirs: tuple[Path, ...], near_m: float, json_out: Path | None, features_out: Path | None) -> None:
    """Score the robot loop's moving test (`tracks[].moving_test` of `fuzzystereo sim suite --record DIR`; pass run
    directories or a suite's record directory) against the simulated world: the share of each verdict among the
    confirmed tracks of moving and of static obstacles, and for the movers near the robot that were tracked before,
    how often a confirmed track still covers them and with which verdict (docs/robot.md "Session 46")."""
    from rich.table import Table

    from .runreport import expand_run_dirs
    from .verdicts import verdicts

    r = verdicts(expand_run_dirs(list(run_dirs)), near_m=near_m)
    v = r["verdicts"]
    names = sorted({k for c in v.values() for k in c["share"]}, key=lambda k: (k != "mover", k))
    t = Table(title=f"moving-test verdicts of confirmed tracks (track-frames), {r['records']} records")
    t.add_column("verdict")
    for col in ("movers", f"movers <= {near_m:g} m", "static", f"static <= {near_m:g} m"):
        t.add_column(col, justify="right")
    for k in names:
        t.add_row(k, *(f"{100 * v[c]['share'].get(k, 0.0):.1f} %" for c in ("mover", "mover_near", "static", "static_near")))
    t.add_row("(track-frames)", *(str(v[c]["n"]) for c in ("mover", "mover_near", "static", "static_near")))
    console.print(t)
    c = r["mover_coverage"]
    u = Table(title=f"movers within {near_m:g} m of the robot, tracked before ({c['n']} mover-frames)")
    u.add_column("best confirmed track within radius + {:g} m".format(r["cover_m"]))
    u.add_column("share", justify="right")
    for k, share in c["share"].items():
        u.add_row(k, f"{100 * share:.1f} %")
    console.print(u)
    _write_json(json_out, r)
    if features_out is not None:
        import csv

        from .verdicts import FEATURE_COLUMNS, feature_rows

        rows = feature_rows(expand_run_dirs(list(run_dirs)))
        features_out.parent.mkdir(parents=True, exist_ok=True)
        with open(features_out, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=FEATURE_COLUMNS)
            w.writeheader()
            w.writerows(rows)
        console.print(f"{len(rows)} track-frames -> {features_out}")


@app.command("suite-diff", short_help="Scenario-by-scenario comparison of closed-loop suite results.")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path, dir_okay=False))
@click.option("--time-change", type=click.FloatRange(0, None), default=None,
              help="Also list scenarios reached in both runs whose time differs by more than this [s].")
@click.option("--json", "json_out", type=_path, default=None, help="Also write the comparison as JSON.")
def suite_diff_cmd(files: tuple[Path, ...], time_change: float | None, json_out: Path | None) -> None:
    """Compare BASE.json NEW.json [BASE2.json NEW2.json ...] (`fuzzystereo sim suite --json`, same
    seed and count per pair): totals, every scenario whose outcome changed, and the exact sign tests of
    the scenarios reached in only one of the two runs and of those with a contact in only one (a small
    p: more than a harmless change's reshuffling; with 2-4 discordant scenarios p is never small)."""
    import math as _math

    from rich.table import Table

    from .suitediff import diff, to_json

    if len(files) % 2:
        raise FatalError(f"suite-diff takes pairs of files (BASE NEW ...); got {len(files)}")
    pairs = [diff(files[i], files[i + 1], _math.inf if time_change is None else time_change)
             for i in range(0, len(files), 2)]
    j = to_json(pairs)
    t = Table(title="closed-loop suites, base -> new")
    for col in ("seed", "reached", "collisions", "struck", "safe stops", "mean time to goal s", "gained", "lost", "sign p",
                "contacts -/+", "contacts p"):
        t.add_column(col, justify="right")
    def mt(v: float | None) -> str:
        return "-" if v is None else f"{v:.1f}"
    for p, pj in zip(pairs, j["pairs"]):
        b, n = p.base, p.new
        t.add_row(str(b.seed), f"{b.reached} -> {n.reached} / {b.solvable}", f"{b.collisions} -> {n.collisions}",
                  f"{b.struck} -> {n.struck}", f"{b.safe_stops} -> {n.safe_stops} / {b.blocked}",
                  f"{mt(b.mean_time_reached_s)} -> {mt(n.mean_time_reached_s)}", str(p.gained), str(p.lost),
                  f"{pj['sign_test_p']:.2f}", f"{p.contacts_fewer} / {p.contacts_more}",
                  f"{pj['contacts_sign_test_p']:.2f}")
    if len(pairs) > 1:
        tot = j["total"]
        t.add_row("all", f"{tot['reached_base']} -> {tot['reached_new']} / {tot['solvable']}",
                  f"{tot['collisions_base']} -> {tot['collisions_new']}", "",
                  f"{tot['safe_stops_base']} -> {tot['safe_stops_new']} / {tot['blocked']}", "",
                  str(tot["gained"]), str(tot["lost"]), f"{tot['sign_test_p']:.2f}",
                  f"{tot['contacts_fewer']} / {tot['contacts_more']}", f"{tot['contacts_sign_test_p']:.2f}")
    console.print(t)
    tot = j["total"]
    console.print(f"contacts {tot['contacts_base']} -> {tot['contacts_new']}: {tot['contacts_fewer']} scenarios lost a "
                  f"contact, {tot['contacts_more']} gained one (sign p = {tot['contacts_sign_test_p']:.2f})")
    for p in pairs:
        if not p.changed:
            console.print(f"seed {p.base.seed}: no scenario changed")
            continue
        c = Table(title=f"seed {p.base.seed}: changed scenarios ({p.base.path} -> {p.new.path})")
        for col in ("scenario", "features", "base", "new", "change"):
            c.add_column(col)
        style = {"better": "green", "worse": "red"}
        for row in p.changed:
            c.add_row(row["scenario"], row["features"], f"{row['base']} {row['base_time_s']:.1f} s",
                      f"{row['new']} {row['new_time_s']:.1f} s",
                      f"[{style.get(row['change'], '')}]{row['change']}[/]" if row["change"] in style else row["change"])
        console.print(c)
    _write_json(json_out, j)


@app.command("targets", short_help="Every issue target measured in one run: table, targets.json, index.html.")
@click.option("--bin", "binary", type=_path, default=None,
              help="fuzzystereo binary (default $FUZZYSTEREO_BIN or build/default/fuzzystereo).")
@click.option("--datasets", type=click.Path(path_type=Path, file_okay=False), default=None,
              help="Stereo datasets (default $FUZZYSTEREO_DATASETS or ../shared/datasets); without them the "
                   "accuracy and speed rows are reported as not measured.")
@click.option("--out", type=_path, default=Path("out/targets"), show_default=True, help="Output directory.")
@click.option("--issues", default="2,4,5", show_default=True, help="Which issues' targets, comma-separated.")
@click.option("--quick", is_flag=True,
              help="Small samples (12 frames, 4 scenarios, 1 bench repeat): checks the chain, not the targets.")
@click.option("--frames", type=click.IntRange(1, 100000), default=300, show_default=True,
              help="Generated frames for detect-eval.")
@click.option("--detect-seed", type=click.IntRange(0, None), default=64, show_default=True)
@click.option("--scenarios", type=click.IntRange(1, 100000), default=100, show_default=True,
              help="Suite scenarios with a free path (plus a tenth without).")
@click.option("--suite-seed", type=click.IntRange(0, None), default=111, show_default=True)
@click.option("--jobs", type=click.IntRange(1, 64), default=2, show_default=True, help="Suite scenarios in parallel.")
@click.option("--repeats", type=click.IntRange(1, 100), default=5, show_default=True, help="bench repeats per frame.")
@click.option("--config", "config_file", type=_existing_file, default=None, help="Config TOML for every command.")
@click.option("--against", type=_existing_file, default=None,
              help="An earlier targets.json: its figures in a 'before' column.")
@click.option("--strict", is_flag=True, help="Exit 1 when a target is missed or not measured.")
def targets_cmd(binary: Path | None, datasets: Path | None, out: Path, issues: str, quick: bool, frames: int,
                detect_seed: int, scenarios: int, suite_seed: int, jobs: int, repeats: int, config_file: Path | None,
                against: Path | None, strict: bool) -> None:
    """Run the firmware's benchmark commands behind every target of issues 2, 4 and 5 (eval clean and
    radiometric, bench, detect-eval on freshly generated frames, the closed-loop suite, the watchdog
    stall on both clocks, track-eval, the bad-input checks) and print one table of target / measured /
    met. The full run takes about 10 minutes on two cores; raw outputs go to OUT/raw/."""
    from .firmware import find_binary
    from .paths import default_datasets_dir
    from .targets import Options, load_previous, previous_of, run_targets, summary

    try:
        wanted = tuple(sorted({int(x) for x in issues.split(",") if x.strip()}))
    except ValueError:
        raise FatalError(f"--issues {issues!r}: expected a comma-separated list of 2, 4, 5") from None
    if not wanted or any(i not in (2, 4, 5) for i in wanted):
        raise FatalError(f"--issues {issues!r}: each must be 2, 4 or 5")
    opt = Options(binary=find_binary(binary), datasets=datasets or default_datasets_dir(), out=out, quick=quick,
                  issues=wanted, detect_frames=12 if quick else frames, detect_seed=detect_seed,
                  suite_count=4 if quick else scenarios, suite_seed=suite_seed, jobs=jobs,
                  bench_repeats=1 if quick else repeats, config=config_file)
    prev = load_previous(against) if against is not None else None
    t0 = __import__("time").monotonic()
    rows, page = run_targets(opt, log=lambda s: err_console.print(s), prev=prev)
    table = Table(title=f"issue targets{' (quick: small samples)' if quick else ''}")
    for col in ("issue", "target", "required", *(("before",) if prev is not None else ()), "measured", ""):
        table.add_column(col)
    mark = {True: "[green]met[/]", False: "[red]missed[/]", None: "[yellow]not measured[/]"}
    plain = {True: "met", False: "missed", None: "not measured"}
    for t in rows:
        before = ()
        if prev is not None:
            p = previous_of(t, prev)
            before = (escape(f"{p['measured']} ({plain[p['met']]})") if p else "-",)
        table.add_row(str(t.issue), escape(t.name), escape(t.target), *before, escape(t.measured), mark[t.met])
    console.print(table)
    s = summary(rows)
    console.print(f"{s['met']} met, {s['missed']} missed, {s['not_measured']} not measured "
                  f"({__import__('time').monotonic() - t0:.0f} s); report {page}")
    if strict and (s["missed"] or s["not_measured"]):
        raise click.exceptions.Exit(1)


# ---- main -----------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fuzzyctl`` console script; returns the exit code."""
    state.verbose = False
    try:
        rv = app.main(args=argv, prog_name="fuzzyctl", standalone_mode=False)
    except FatalError as exc:
        if state.verbose:
            traceback.print_exc()
        err_console.print(f"[bold red]fuzzyctl: error:[/] {escape(str(exc))}", soft_wrap=True)
        return exc.exit_code
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        err_console.print("fuzzyctl: aborted")
        return 130
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    except KeyboardInterrupt:
        err_console.print("fuzzyctl: interrupted")
        return 130
    except OSError as exc:
        # A file or directory the command could not create, read or write (e.g. --out in a
        # read-only place): one line naming it, as for every other user error.
        if state.verbose:
            traceback.print_exc()
        what = exc.strerror or str(exc)
        name = f": {exc.filename}" if exc.filename else ""
        err_console.print(f"[bold red]fuzzyctl: error:[/] {escape(what + name)}", soft_wrap=True)
        return 2
    return rv if isinstance(rv, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
