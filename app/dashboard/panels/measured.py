"""A measured loop as the dashboard shows it: the Bode plot as an image and the comparison as text
(hopper.analysis.bench.Measurement, drawn by hopper.report.frequency). Call off the loop's thread:
drawing takes ~0.3 s."""

from __future__ import annotations

import html
from typing import TYPE_CHECKING

import numpy as np
import viser

if TYPE_CHECKING:  # matplotlib and scipy load when a measurement is drawn, not with the dashboard
    from hopper.analysis.bench import Measurement

SIZE_IN = (6.4, 5.2)  # inches at the figure's dpi: legible in the 20 rem side panel when enlarged


def bode_image(result: Measurement) -> np.ndarray:
    """The measured Bode plot over the model's, RGB (h, w, 3) uint8."""
    from hopper.report import frequency, style

    fig = frequency.bode(result.to_json())
    try:
        fig.set_size_inches(*SIZE_IN)
        fig.tight_layout()
        fig.canvas.draw()
        return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    finally:
        style.close(fig)


def measured_html(result: Measurement) -> str:
    """The comparison's lines (measured beside predicted), preformatted."""
    text = "<br>".join(html.escape(line).replace("  ", "&nbsp;&nbsp;") for line in result.lines())
    return f"<div class='hd-measured'><pre>{text}</pre></div>"


def summary(result: Measurement) -> str:
    """One line for a notification."""
    m = result.measured
    return f"crossover {m.crossover_hz:.2f} Hz, phase margin {m.phase_margin_deg:.1f} deg" if m else result.note


def blank() -> np.ndarray:
    """What an image handle holds before its first plot (hidden)."""
    return np.full((8, 8, 3), 255, np.uint8)


def show(result: Measurement, image: np.ndarray, bode: viser.GuiImageHandle, text: viser.GuiHtmlHandle) -> None:
    """Put a measurement on the panel: its plot in `bode` (shown), its comparison in `text`."""
    bode.image = image
    bode.visible = True
    text.content = measured_html(result)


def failed_html(why: str) -> str:
    return f"<div class='hd-measured hd-bad'>not measured: {html.escape(why)}</div>"
