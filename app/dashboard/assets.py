"""The dashboard's own web assets: static/ (the package hopper.static), installed or not."""

from __future__ import annotations

import base64
import dataclasses
import functools
import json
from importlib import resources

STATIC = resources.files("hopper.static")


@dataclasses.dataclass(frozen=True)
class Theme:
    """Colours and panel sizes from static/theme.json."""

    dark_mode: bool = True
    brand_color: tuple[int, int, int] = (255, 176, 59)
    control_width: str = "medium"
    left_panel_width: int = 400
    right_panel_width: int = 330


def _read(name: str) -> str:
    path = STATIC / name
    if not path.is_file():
        raise FileNotFoundError(f"missing dashboard asset {name} in the package hopper.static")
    return path.read_text(encoding="utf-8")


@functools.cache
def help_markdown() -> str:
    return _read("help.md")


@functools.cache
def stylesheet() -> str:
    return _read("dashboard.css")


@functools.cache
def logo_data_uri() -> str:
    """The SVG logo as a data: URI, so it needs no extra HTTP route."""
    return "data:image/svg+xml;base64," + base64.b64encode(_read("logo.svg").encode()).decode()


@functools.cache
def theme() -> Theme:
    raw = json.loads(_read("theme.json"))
    return Theme(**{**raw, "brand_color": tuple(raw.get("brand_color", Theme.brand_color))})


@functools.cache
def chart_runtime() -> str:
    """static/charts.js: the page's side of the live charts' feed (hopper.app.dashboard.chart_feed)."""
    return _read("charts.js")


@functools.cache
def status_runtime() -> str:
    """static/status.js: the page's side of the status strip (hopper.app.dashboard.panels.status)."""
    return _read("status.js")
