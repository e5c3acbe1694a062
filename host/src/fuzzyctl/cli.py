"""The ``fuzzyctl`` command line. Thin: parse options, call one library function, print.

Every user or device fault is a :class:`~fuzzyctl.errors.FatalError`, caught once in :func:`main`
and printed as one line (exit code 2); ``--verbose`` adds the traceback.
"""

from __future__ import annotations

import sys
import traceback
from pathlib import Path
from typing import Optional

import click
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from . import __version__
from .errors import FatalError

console = Console()
err_console = Console(stderr=True)


class _State:
    verbose = False


state = _State()

app = typer.Typer(
    name="fuzzyctl",
    help="Host tools for fuzzystereo: FIS checks, the float64 desktop reference, firmware comparison.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
fis_app = typer.Typer(help="The fuzzy inference system (eq. 10-12, Table I).", no_args_is_help=True)
config_app = typer.Typer(help="Matcher configuration (common/config/schema.toml).", no_args_is_help=True)
reference_app = typer.Typer(help="The float64 desktop reference of the matcher.", no_args_is_help=True)
app.add_typer(fis_app, name="fis")
app.add_typer(config_app, name="config")
app.add_typer(reference_app, name="reference")


def _version(value: bool) -> None:
    if value:
        console.print(f"fuzzyctl {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Show tracebacks for errors."),
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version."),
) -> None:
    state.verbose = verbose


# ---- fis ------------------------------------------------------------------------------------


@fis_app.command("plot")
def fis_plot(
    out: Path = typer.Option(..., "--out", help="Directory for the PNG files."),
    fis_file: Optional[Path] = typer.Option(None, "--fis", help="FIS definition (default common/fis/fis.toml)."),
    points: int = typer.Option(101, "--points", min=5, max=1001, help="Surface grid size per axis."),
) -> None:
    """Membership functions of dc1, dc2 and the output, and the FIS surface, as PNG."""
    from .fis import Fis, load_definition
    from .plots import write_fis_plots

    fis = Fis(load_definition(fis_file))
    for path in write_fis_plots(fis, out, surface_points=points):
        console.print(f"wrote {path}")


@fis_app.command("show")
def fis_show(
    fis_file: Optional[Path] = typer.Option(None, "--fis", help="FIS definition (default common/fis/fis.toml)."),
) -> None:
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


@fis_app.command("eval")
def fis_eval_cmd(
    dc1: float = typer.Argument(..., min=0.0, max=1.0, help="Data Cost 1 in [0, 1]."),
    dc2: float = typer.Argument(..., min=0.0, max=1.0, help="Data Cost 2 in [0, 1]."),
    fis_file: Optional[Path] = typer.Option(None, "--fis", help="FIS definition (default common/fis/fis.toml)."),
) -> None:
    """FIS output for one pair, computed by scikit-fuzzy's ControlSystemSimulation."""
    from .fis import Fis, load_definition

    console.print(f"{Fis(load_definition(fis_file)).evaluate(dc1, dc2):.9f}")


@fis_app.command("check")
def fis_check(
    points: int = typer.Option(1000, "--points", min=1, help="Random input pairs (corners/edges are added)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the random pairs."),
    binary: Optional[Path] = typer.Option(None, "--bin", help="fuzzystereo binary (default $FUZZYSTEREO_BIN or build/default/fuzzystereo)."),
    fis_file: Optional[Path] = typer.Option(None, "--fis", help="FIS definition passed to both sides."),
    config_file: Optional[Path] = typer.Option(None, "--config", help="Config passed to the firmware (fis.lut_size)."),
    tolerance: float = typer.Option(0.01, "--tolerance", help="Max |LUT - scikit-fuzzy| (default 1 % of [0, 1])."),
) -> None:
    """Firmware `fis eval` (LUT and exact) against scikit-fuzzy; non-zero exit above tolerance."""
    from .firmware import find_binary
    from .fischeck import EXACT_TOLERANCE, check_firmware_fis

    exe = find_binary(binary)
    res = check_firmware_fis(exe, n_random=points, seed=seed, fis_path=fis_file, config_path=config_file)
    table = Table(title=f"firmware FIS vs scikit-fuzzy ({len(res.dc1)} pairs, seed {seed})")
    for col in ("firmware output", "max |error|", "mean |error|", "worst at (dc1, dc2)", "tolerance"):
        table.add_column(col)
    for name, err, tol in (("LUT (fixed point)", res.lut_error, tolerance), ("exact (double)", res.exact_error, EXACT_TOLERANCE)):
        worst, a, b = res.worst(err)
        table.add_row(name, f"{worst:.3g}", f"{err.mean():.3g}", f"({a:.4f}, {b:.4f})", f"{tol:g}")
    console.print(table)
    lut_max = float(res.lut_error.max())
    if lut_max > tolerance:
        raise FatalError(f"FIS LUT max abs error {lut_max:.4g} exceeds {tolerance:g}")
    console.print(f"max abs error (LUT) {lut_max:.4g} <= {tolerance:g}: OK")


# ---- config ---------------------------------------------------------------------------------


@config_app.command("check")
def config_check(path: Path = typer.Argument(..., help="TOML config to validate.")) -> None:
    """Validate a config file against the schema (defaults fill missing fields)."""
    from .config import load_config

    load_config(path)
    console.print(f"{path}: OK")


@config_app.command("show")
def config_show(path: Optional[Path] = typer.Argument(None, help="TOML config (default: the defaults).")) -> None:
    """Print the resolved config as TOML."""
    from .config import load_config

    console.print(load_config(path).to_toml(), end="", markup=False, highlight=False)


@config_app.command("schema")
def config_schema() -> None:
    """Every config field with its type, range and meaning."""
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


# ---- main -----------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fuzzyctl`` console script; returns the exit code."""
    state.verbose = False
    try:
        rv = app(args=argv, prog_name="fuzzyctl", standalone_mode=False)
    except FatalError as exc:
        if state.verbose:
            traceback.print_exc()
        err_console.print(f"[bold red]fuzzyctl: error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
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
