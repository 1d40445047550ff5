"""The figures' shared look: Agg backend, one palette, sizes, and the PNG / PDF writer."""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless: files only, never a window

import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

WHEEL_ON = "#1f6fb4"  # blue
WHEEL_OFF = "#d1495b"  # red
SECOND = "#e0892b"  # orange: a second quantity on a twin axis (wheel rpm)
LIMIT = "#b22222"  # limit lines
PAPER = "#2e8b57"  # the paper's reported ranges
FLIGHT = "#dbe6f3"  # shading of flight phases
GRID = {"color": "#cccccc", "linewidth": 0.5}
WIDTH = 9.0  # in
DPI = 130

plt.rcParams.update(
    {
        "font.size": 9,
        "axes.titlesize": 10,
        "axes.labelsize": 9,
        "legend.fontsize": 8,
        "axes.spines.top": False,
        "axes.spines.right": False,
        "figure.dpi": DPI,
        "savefig.dpi": DPI,
        "pdf.fonttype": 42,  # TrueType in PDFs: text stays text
    }
)


def new_figure(rows: int = 1, height: float = 2.4, title: str = "", sharex: bool = True) -> tuple[Figure, list]:
    """A figure `WIDTH` wide with `rows` axes stacked (each `height` in tall), and its axes list."""
    fig, axes = plt.subplots(rows, 1, figsize=(WIDTH, height * rows + 0.5), sharex=sharex, squeeze=False)
    if title:
        fig.suptitle(title, fontsize=11)
    for ax in axes[:, 0]:
        ax.grid(True, **GRID)
    return fig, list(axes[:, 0])


def legend_above(ax, handles: list | None = None, labels: list | None = None) -> None:  # noqa: ANN001 (Axes)
    """The legend in one row above the axes, clear of the data; none for axes with nothing labelled (a
    group drawn as a line of text, hopper.report.run_figures._bars)."""
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    ax.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=len(handles), frameon=False,
              borderaxespad=0.2)  # fmt: skip


def save(fig: Figure, folder: Path, name: str) -> list[Path]:
    """Write `fig` as folder/name.png and folder/name.pdf; returns both paths."""
    fig.tight_layout()
    paths = [folder / f"{name}.png", folder / f"{name}.pdf"]
    for path in paths:
        fig.savefig(path)
    return paths


def png_bytes(fig: Figure) -> bytes:
    """The figure as PNG bytes (for embedding in the HTML page)."""
    buffer = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


def close(fig: Figure) -> None:
    plt.close(fig)
