"""The flight envelope's figure: every kick flown, by moment and size, under the physical limit's curve."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hopper.analysis.envelope import Moment, physical_limit, wheel_reach
from hopper.experiments.stress import LANDING_LIMIT_DEG, Outcome
from hopper.report import style

KINDS = (  # outcome, marker, colour, label
    ("landed", "o", "#2e8b57", f"landed within {LANDING_LIMIT_DEG:g} deg"),
    ("off", "s", "#e0892b", f"landed beyond {LANDING_LIMIT_DEG:g} deg, stood"),
    ("fell", "x", "#b22222", "fell"),
)


FILES = ("envelope.png", "envelope.pdf", "envelope.json")  # what `hopper-sim envelope --out` writes


def is_envelope_folder(folder: Path) -> bool:
    """`folder` holds an envelope (its envelope.json) and nothing else than FILES: what a new envelope
    may replace whole."""
    return (folder / FILES[-1]).is_file() and all(p.is_file() and p.name in FILES for p in folder.iterdir())


def _kind(outcome: Outcome) -> str:
    if outcome.fell:
        return "fell"
    return "landed" if outcome.worst_landing_deg <= LANDING_LIMIT_DEG else "off"


def figure(outcomes: list[Outcome], moments: list[Moment], folder: Path) -> list[Path]:
    """envelope.png / .pdf in `folder`: one panel per kick direction; returns the paths."""
    fig, axes = style.new_figure(2, 3.0, "Pitch kicks in flight: what the controller recovers, against physics")
    t = np.array([m.t for m in moments])
    for ax, sign in zip(axes, (1.0, -1.0), strict=True):
        limit = [physical_limit(m, sign) for m in moments]
        ax.plot(t, limit, color=style.LIMIT, label="physical limit (wheel, legs, torque)")
        ax.plot(t, [wheel_reach(m, sign) for m in moments], color=style.LIMIT, linestyle="--", linewidth=0.8,
                label="the wheel's reachable headroom alone")  # fmt: skip
        for kind, marker, colour, label in KINDS:
            here = [o for o in outcomes if _kind(o) == kind and o.case.disturbance.magnitude * sign > 0]  # type: ignore[union-attr]
            if here:
                ax.scatter([o.case.disturbance.delay_s for o in here],  # type: ignore[union-attr]
                           [abs(o.case.disturbance.magnitude) for o in here],  # type: ignore[union-attr]
                           marker=marker, color=colour, s=18, label=label, zorder=3)  # fmt: skip
        ax.set_ylabel(f"{'nose-down (+)' if sign > 0 else 'nose-up (-)'} kick, N m s")
        ax.set_ylim(0.0, None)
    handles, labels = axes[0].get_legend_handles_labels()
    for ax in axes[1:]:  # a marker kind missing from the top panel
        for h, label in zip(*ax.get_legend_handles_labels(), strict=True):
            if label not in labels:
                handles.append(h)
                labels.append(label)
    axes[0].legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=3, frameon=False)
    axes[-1].set_xlabel("moment of the kick, s after liftoff (touchdown at the right edge)")
    axes[-1].set_xlim(0.0, moments[-1].t + moments[-1].to_go)
    paths = style.save(fig, folder, "envelope")
    style.close(fig)
    return paths
