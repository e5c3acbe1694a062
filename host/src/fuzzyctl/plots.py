"""Matplotlib figures (Agg backend, PNG): FIS membership functions and surface, disparity maps."""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .fis import Fis, Variable  # noqa: E402


def _plot_variable(ax, var: Variable, universe: np.ndarray, title: str) -> None:
    for term in var.terms:
        ax.plot(universe, term.membership(universe), label=term.name, lw=1.4)
    ax.set_title(title)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.05)
    ax.set_xlabel(var.name)
    ax.set_ylabel("membership")
    ax.legend(fontsize=7, ncol=3 if len(var.terms) > 8 else 2, loc="upper center",
              bbox_to_anchor=(0.5, -0.18), frameon=False)


def membership_figure(fis: Fis, which: str):
    """Figure of the terms of ``dc1``, ``dc2`` or ``output`` (eq. 10, 11, 12)."""
    d = fis.defn
    var, universe, eq = {
        "dc1": (d.dc1, d.input_universe, "(10)"),
        "dc2": (d.dc2, d.input_universe, "(11)"),
        "output": (d.output, d.output_universe, "(12)"),
    }[which]
    fig, ax = plt.subplots(figsize=(8 if which == "output" else 6, 4.2), constrained_layout=True)
    _plot_variable(ax, var, universe, f"{var.label} — eq. {eq}")
    return fig


def surface_grid(fis: Fis, n: int = 101, exact: bool = False):
    """(a, b, z): FIS output on an n x n grid over [0, 1]^2 (z[i, j] = FIS(a[i], b[j]))."""
    a = np.linspace(0.0, 1.0, n)
    A, B = np.meshgrid(a, a, indexing="ij")
    z = fis.evaluate_many(A, B) if exact else fis.evaluate_fast(A, B)
    return a, a, z.reshape(A.shape)


def surface_figure(fis: Fis, n: int = 101):
    """3-D surface and top view of FIS(dc1, dc2) (Table I)."""
    a, b, z = surface_grid(fis, n)
    A, B = np.meshgrid(a, b, indexing="ij")
    fig = plt.figure(figsize=(11, 4.6), constrained_layout=True)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.plot_surface(A, B, z, cmap="viridis", linewidth=0, antialiased=True)
    ax.set_xlabel("dc1 (NCC)")
    ax.set_ylabel("dc2")
    ax.set_zlabel(fis.defn.output.name)
    ax.set_title(f"FIS surface ({fis.defn.name})")
    ax2 = fig.add_subplot(1, 2, 2)
    im = ax2.imshow(z.T, origin="lower", extent=(0, 1, 0, 1), cmap="viridis", vmin=0, vmax=1, aspect="equal")
    ax2.set_xlabel("dc1 (NCC)")
    ax2.set_ylabel("dc2 = alpha NMI + (1 - alpha) IGSAD")
    ax2.set_title("top view")
    fig.colorbar(im, ax=ax2, label=fis.defn.output.name)
    return fig


def save(fig, path: str | Path) -> Path:
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def png_bytes(fig, dpi: int = 90, tight: bool = False) -> bytes:
    """The figure as PNG bytes; closes it. ``tight`` crops the margins (bbox_inches="tight")."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, **({"bbox_inches": "tight"} if tight else {}))
    plt.close(fig)
    return buf.getvalue()


def write_fis_plots(fis: Fis, out_dir: str | Path, surface_points: int = 101) -> list[Path]:
    """PNG files: fis_dc1.png, fis_dc2.png, fis_output.png, fis_surface.png."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = [save(membership_figure(fis, w), out / f"fis_{w}.png") for w in ("dc1", "dc2", "output")]
    written.append(save(surface_figure(fis, surface_points), out / "fis_surface.png"))
    return written
