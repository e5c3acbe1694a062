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


# ---- reference ------------------------------------------------------------------------------


@app.group("reference", short_help="The float64 desktop reference of the matcher.")
def reference_group() -> None:
    """The float64 desktop reference of the matcher (the firmware's oracle)."""


_engine_option = click.option(
    "--fis-engine", "engine", type=click.Choice(["fast", "skfuzzy"]), default="fast", show_default=True,
    help="fast: vectorised twin of scikit-fuzzy's arithmetic, cross-checked against ControlSystemSimulation "
    "on samples; skfuzzy: ControlSystemSimulation for every distinct pair (slow).",
)


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


# ---- compare --------------------------------------------------------------------------------


@app.command("compare")
@click.argument("run_dir", type=_path)
@click.option("--tolerances", type=_path, default=None, help="Tolerances TOML (default common/compare/tolerances.toml).")
@click.option("--report", type=_path, default=None, help="Write a self-contained HTML report here.")
@click.option("--reference-out", type=_path, default=None, help="Also write the reference's outputs (dump format) here.")
@click.option("--own-segmentation", is_flag=True, help="Let the reference run its own SLIC instead of reusing the firmware's labels.")
@_fis_option
@_engine_option
def compare_cmd(run_dir: Path, tolerances: Path | None, report: Path | None, reference_out: Path | None,
                own_segmentation: bool, fis_file: Path | None, engine: str) -> None:
    """Firmware dump (RUN_DIR/dump or RUN_DIR) vs the float64 reference, stage by stage."""
    from .compare import compare_run
    from .errors import CheckFailed

    with console.status("running the reference on the dump ..."):
        c = compare_run(run_dir, tolerances, fis_file, engine=engine, own_segmentation=own_segmentation)
    table = Table(title=f"firmware vs reference — {c.dump.path}")
    table.add_column("stage", no_wrap=True, min_width=12)
    table.add_column("metric", no_wrap=True, min_width=36)
    for col in ("value", "tolerance", "status"):
        table.add_column(col, no_wrap=True)
    failing = {m.name for m, _ in c.failures()}
    for m in c.metrics:
        tol = c.tolerances.get(m.name)
        value = "n/a" if m.value is None else (f"{m.value:.3f} %" if m.unit == "%" else f"{m.value:.4g}")
        status = "" if tol is None else ("n/a" if m.value is None else "[red]FAIL[/]" if m.name in failing else "[green]ok[/]")
        table.add_row(m.stage, m.name, value, tol.text() if tol else "", status)
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
    return rv if isinstance(rv, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
