"""Figures of a measured loop: the Bode plot of the measurement over the model's, and a step response.

They read the JSON document `hopper-sim stand --json` writes (kind "frequency"; its measurements
as hopper.analysis.bench.Measurement.to_json gives them), so a report needs no simulation.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure

from hopper.report import page, style
from hopper.report.build import Named, Report

MEASURED = style.WHEEL_ON
PREDICTED = style.SECOND
COHERENCE_TRUSTED = 0.8  # hopper.analysis.frequency: below it an estimate is not to be trusted


def _complex(data: dict[str, Any], key: str) -> np.ndarray | None:
    if data.get(f"{key}_re") is None:
        return None
    return np.asarray(data[f"{key}_re"], float) + 1j * np.asarray(data[f"{key}_im"], float)


def _margin_text(margins: dict[str, float] | None) -> str:
    if not margins or margins.get("crossover_hz") is None:
        return "-"
    fc, pm = margins["crossover_hz"], margins["phase_margin_deg"]
    return f"{fc:.2f} Hz, PM {pm:.1f} deg"


def bode(measurement: dict[str, Any]) -> Figure:
    """|L| (dB), its phase (deg) and the coherence against frequency (Hz): measured points, the
    model's curve; at the reference, T (r -> pitch) instead of L."""
    f = np.asarray(measurement["f"], float)
    measured, predicted = _complex(measurement, "measured"), _complex(measurement, "predicted")
    coherence = np.asarray(measurement["coherence"], float)
    what = "L" if measurement["at"] == "input" else "T (reference to pitch)"
    where = "in flight" if measurement["where"] == "flight" else f"on the {measurement['where']}"
    title = f"{what} measured {where}, {measurement['controller']}"
    fig, (mag, phase, coh) = style.new_figure(3, 2.0, title)
    trusted = coherence >= COHERENCE_TRUSTED
    for ax, values in ((mag, 20 * np.log10(np.abs(measured))), (phase, np.degrees(np.unwrap(np.angle(measured))))):
        ax.semilogx(f[trusted], values[trusted], ".", color=MEASURED, ms=3, label="measured")
        if (~trusted).any():
            ax.semilogx(f[~trusted], values[~trusted], ".", color="#9bb7d4", ms=3, label="measured, coherence < 0.8")
    if predicted is not None:
        mag.semilogx(f, 20 * np.log10(np.abs(predicted)), "-", color=PREDICTED, lw=1.4, label="predicted (model)")
        phase.semilogx(f, np.degrees(np.unwrap(np.angle(predicted))), "-", color=PREDICTED, lw=1.4)
    if measurement["at"] == "input":
        mag.axhline(0.0, color="#888888", lw=0.8)
        phase.axhline(-180.0, color="#888888", lw=0.8)
        phase.axhline(180.0, color="#888888", lw=0.8)
        for margins, color in (
            (measurement.get("measured_margins"), MEASURED),
            (measurement.get("predicted_margins"), PREDICTED),
        ):
            if margins and margins.get("crossover_hz") is not None:
                for ax in (mag, phase, coh):
                    ax.axvline(margins["crossover_hz"], color=color, lw=0.8, ls="--")
        note = f"crossover: measured {_margin_text(measurement.get('measured_margins'))}; "
        note += f"predicted {_margin_text(measurement.get('predicted_margins'))}"
        mag.text(0.99, 0.94, note, transform=mag.transAxes, ha="right", va="top", fontsize=8,
                 bbox={"facecolor": "white", "edgecolor": "#cccccc", "boxstyle": "round,pad=0.3"})  # fmt: skip
    mag.set_ylabel(f"|{what.split()[0]}| (dB)")
    phase.set_ylabel("phase (deg)")
    coh.semilogx(f, coherence, "-", color=MEASURED, lw=1.0)
    coh.axhline(COHERENCE_TRUSTED, color=style.LIMIT, lw=0.8, ls=":")
    coh.set_ylim(0.0, 1.05)
    coh.set_ylabel("coherence")
    coh.set_xlabel("frequency (Hz)")
    style.legend_above(mag)
    return fig


def step(step_data: dict[str, Any]) -> Figure:
    """The pitch (deg) after a step of the reference, measured and predicted, against time (ms)."""
    t = np.asarray(step_data["t"], float) * 1e3
    fig, (ax,) = style.new_figure(1, 2.8, f"Step of the pitch reference, {step_data['step_deg']:g} deg")
    ax.plot(t, np.degrees(step_data["measured"]), color=MEASURED, lw=1.6, label="measured")
    if step_data.get("predicted") is not None:
        ax.plot(t, np.degrees(step_data["predicted"]), color=PREDICTED, lw=1.0, ls="--", label="predicted (model)")
    ax.axhline(step_data["step_deg"], color="#888888", lw=0.8)
    ax.set_xlabel("time since the step (ms)")
    ax.set_ylabel("pitch (deg)")
    style.legend_above(ax)
    return fig


def kick(kick_data: dict[str, Any]) -> Figure:
    """The pitch (deg) after a pitch kick on the stand against time (ms), its peak and the 10 % band
    it is back within from the time the document gives."""
    t = np.asarray(kick_data["t"], float) * 1e3
    peak, back = kick_data["peak_pitch_deg"], kick_data["back_within_10pct_s"] * 1e3
    fig, (ax,) = style.new_figure(1, 2.8, f"Pitch kick on the stand, {kick_data['magnitude_nms']:g} N m s")
    ax.plot(t, kick_data["pitch_deg"], color=MEASURED, lw=1.6, label="measured")
    ax.axhspan(-0.1 * peak, 0.1 * peak, color="#888888", alpha=0.15, lw=0, label="within 10 % of the peak")
    ax.axvline(back, color="#888888", lw=0.8, ls="--")
    ax.axhline(0.0, color="#888888", lw=0.8)
    ax.annotate(f"peak {peak:.3g} deg at {kick_data['peak_s'] * 1e3:.0f} ms; back within 10 % from {back:.0f} ms",
                (0.99, 0.94), xycoords="axes fraction", ha="right", va="top", fontsize=8,
                bbox={"facecolor": "white", "edgecolor": "#cccccc", "boxstyle": "round,pad=0.3"})  # fmt: skip
    ax.set_xlabel("time since the kick (ms)")
    ax.set_ylabel("pitch (deg)")
    style.legend_above(ax)
    return fig


def frequency_report(document: dict[str, Any], title: str) -> Report:
    """The document's Bode plots and step response, with a table of measured against predicted."""
    figures, rows = [], []
    for i, m in enumerate(document.get("measurements", [])):
        name = f"bode_{i + 1}"
        caption = (
            f"{m['spec']['kind']} chirp {m['spec']['f_min']:g}-{m['spec']['f_max']:g} Hz, {m['records']} record(s)"
        )
        figures.append(Named(name, f"Bode: {m['where']}, {m['controller']}", caption, bode(m)))
        mm, pm = m.get("measured_margins") or {}, m.get("predicted_margins") or {}
        for label, key in (("crossover (Hz)", "crossover_hz"), ("phase margin (deg)", "phase_margin_deg")):
            rows.append([m["where"], m["controller"], label, mm.get(key, "-"), pm.get(key, "-")])
        if m.get("note"):
            rows.append([m["where"], m["controller"], "note", m["note"], ""])
    if document.get("step"):
        s = document["step"]
        figures.append(Named("step", "Step response", "measured on the stand against the model's closed loop", step(s)))
        for key, label in (("rise_s", "rise (s)"), ("overshoot_pct", "overshoot (%)"), ("settling_s", "settling (s)")):
            predicted = (s.get("predicted_metrics") or {}).get(key, "-")
            rows.append(["stand", "step", label, s["measured_metrics"][key], predicted])
    if document.get("kick"):
        k = document["kick"]
        if k.get("t"):  # older documents hold the figures only
            caption = "measured on the stand: the kick's angular momentum added to the torso at t = 0"
            figures.append(Named("kick", "Kick response", caption, kick(k)))
        what = f"kick {k['magnitude_nms']:g} N m s"
        rows.append(["stand", what, "peak pitch (deg)", k["peak_pitch_deg"], "-"])
        rows.append(["stand", what, "peak at (ms)", k["peak_s"] * 1e3, "-"])
        rows.append(["stand", what, "back within 10 % from (ms)", k["back_within_10pct_s"] * 1e3, "-"])
    header = ["where", "controller", "figure", "measured", "predicted"]
    table = page.Section("Measured against predicted", header=header, rows=rows)
    subtitle = f"hopper-sim stand, version {document.get('version', '?')}"
    return Report(title, subtitle, document.get("settings", {}), figures, [table])
