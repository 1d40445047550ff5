"""One self-contained HTML page: the figures as base64 PNG, the settings and the tables, no links out."""

from __future__ import annotations

import base64
import dataclasses
import html
from collections.abc import Sequence
from typing import Any

from hopper.config import unit_of

CSS = """
body { font-family: system-ui, sans-serif; max-width: 1000px; margin: 1.5em auto; padding: 0 1em; color: #222; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.6em; border-bottom: 1px solid #ddd; }
table { border-collapse: collapse; font-size: 0.85em; margin: 0.5em 0; }
td, th { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th { background: #f2f2f2; } td.key { text-align: left; font-family: monospace; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: 0.85em; color: #444; }
.note { font-size: 0.85em; color: #555; }
"""


@dataclasses.dataclass(frozen=True)
class Section:
    """A figure (PNG bytes) with its caption, or a table (header, rows) with a title, or a note."""

    title: str
    png: bytes | None = None
    caption: str = ""
    header: Sequence[str] = ()
    rows: Sequence[Sequence[Any]] = ()
    note: str = ""
    pre: str = ""  # preformatted text (a spec file)


def flatten(settings: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """Nested settings as (dotted key, value) pairs, e.g. ('gains.kp', 450.0)."""
    out: list[tuple[str, Any]] = []
    for key, value in settings.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out += flatten(value, name + ".")
        else:
            out.append((name, value))
    return out


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.0f}"
    return html.escape(str(value))


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]], first_is_key: bool = False) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = []
    for row in rows:
        cells = [
            f'<td class="key">{_cell(v)}</td>' if first_is_key and i == 0 else f"<td>{_cell(v)}</td>"
            for i, v in enumerate(row)
        ]
        body.append(f"<tr>{''.join(cells)}</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def render(title: str, subtitle: str, settings: dict[str, Any], sections: Sequence[Section]) -> str:
    """The page: title, the settings (flattened), then each section in order."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f'<p class="note">{html.escape(subtitle)}</p>',
        "<h2>Settings</h2>",
        _table(("setting", "value", "unit"), [(k, v, unit_of(k)) for k, v in flatten(settings)], first_is_key=True),
    ]
    for s in sections:
        parts.append(f"<h2>{html.escape(s.title)}</h2>")
        if s.png is not None:
            data = base64.b64encode(s.png).decode("ascii")
            parts.append(
                f'<figure><img alt="{html.escape(s.title)}" src="data:image/png;base64,{data}">'
                f"<figcaption>{html.escape(s.caption)}</figcaption></figure>"
            )
        if s.rows:
            parts.append(_table(s.header, s.rows))
        if s.note:
            parts.append(f'<p class="note">{html.escape(s.note)}</p>')
        if s.pre:
            parts.append(f"<pre>{html.escape(s.pre)}</pre>")
    parts.append("</body></html>")
    return "\n".join(parts)
