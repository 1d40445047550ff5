"""Telling users what happened: notifications, value checks for browser input, and guarded callbacks."""

from __future__ import annotations

import functools
import logging
import math
import re
import threading
import time
import weakref
from collections.abc import Callable
from typing import Any, Literal

import viser
from hopper.app.dashboard.viser_compat import page_may_close

from hopper.errors import HopperError

log = logging.getLogger(__name__)

Level = Literal["info", "warning", "error"]
_COLORS: dict[Level, Any] = {"info": "blue", "warning": "yellow", "error": "red"}
AUTO_CLOSE_S: dict[Level, float] = {"info": 4.0, "warning": 6.0, "error": 8.0}
# What a person types for a number: digits with an optional point and exponent. Stricter than
# float(), which also takes "nan", "inf", "1_000" and surrounding junk.
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")

_clock = time.monotonic  # tests move time forward
# Per client: (title, body) -> when that notification closes on its own. Weak keys: a client that
# leaves takes its entries with it.
_on_screen: weakref.WeakKeyDictionary[Any, dict[tuple[str, str], float]] = weakref.WeakKeyDictionary()
_on_screen_lock = threading.Lock()


class Refused(HopperError, ValueError):
    """A value from a browser that cannot be used at all (non-finite, wrong type)."""


def format_number(value: float) -> str:
    """A number as people write it: whole numbers in full (2147483647, not 2.14748e+09), others to 6 digits."""
    if isinstance(value, int) or (math.isfinite(value) and value == int(value) and abs(value) < 1e15):
        return str(int(value))
    return f"{value:g}"


def notify(client: viser.ClientHandle | None, title: str, body: str, level: Level = "info") -> None:
    """Show a notification to one client, unless the same one is still on its screen; never raises.

    Identical notifications in a row (a fall replayed after the auto reset, a refusal repeated)
    would otherwise stack as copies.
    """
    if client is None:
        return
    now, key = _clock(), (title, body)
    with _on_screen_lock:
        shown = _on_screen.setdefault(client, {})
        for old in [k for k, until in shown.items() if until <= now]:
            del shown[old]
        if key in shown:
            return
        shown[key] = now + AUTO_CLOSE_S[level]
    try:
        with page_may_close(client):  # a page that closed since is simply not told
            client.add_notification(title, body, color=_COLORS[level], auto_close_seconds=AUTO_CLOSE_S[level])
    except Exception:  # a disconnecting client must not break the caller
        log.debug("notification to client %s failed", getattr(client, "client_id", "?"), exc_info=True)


def notify_all(server: viser.ViserServer, title: str, body: str, level: Level = "info") -> None:
    """Show a notification to every connected client."""
    for client in server.get_clients().values():
        notify(client, title, body, level)


def _clamp(
    name: str,
    value: float,
    low: float,
    high: float,
    unit: str,
    *,
    above: bool = False,
    below: bool = False,
    why: str = "",
) -> tuple[float, str | None]:
    """`value` clamped to [low, high], with the message that says so; Refused where the bound it
    passed is excluded (`above`: value > low; `below`: value < high), which has no nearest value.
    `why` names what sets `high` (the motor's limit), told when the value passes it."""
    if (low < value if above else low <= value) and (value < high if below else value <= high):
        return value, None
    u = f" {unit}" if unit else ""
    f = format_number
    span = f"{'(' if above else '['}{f(low)}, {f(high)}{')' if below else ']'}{u}"
    if why and value >= high:
        span += f" ({why})"
    if (above and value <= low) or (below and value >= high):
        raise Refused(f"{name} {f(value)}{u} is outside {span}")
    clamped = min(max(value, low), high)
    return clamped, f"{name} {f(value)}{u} is outside {span}; clamped to {f(clamped)}{u}"


def checked(name: str, value: object, low: float, high: float, unit: str = "") -> tuple[float, str | None]:
    """A browser value as a float in [low, high]: clamped with a message, or Refused if unusable.

    Returns (value, message); message is None when the value was already in range.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise Refused(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise Refused(f"{name} must be finite, got {value!r}; kept the previous value")
    return _clamp(name, float(value), low, high, unit)


def parse_number(
    name: str,
    text: str,
    low: float,
    high: float,
    unit: str = "",
    *,
    integer: bool = False,
    above: bool = False,
    below: bool = False,
    why: str = "",
) -> tuple[float, str | None]:
    """Typed text as a number in [low, high] (an int if `integer`): clamped with a message, or Refused.

    Takes 800, 12.5, -2.5, 1e3; refuses 1,5 (a decimal comma), abc, NaN, inf and the empty box, and
    a number at or past a bound that is excluded (`above` low, `below` high: see `_clamp`).
    """
    typed = text.strip()
    if not typed:
        raise Refused(f"{name} is empty: type a number")
    if not _NUMBER.fullmatch(typed):
        hint = "; use a point for decimals" if "," in typed else ""
        raise Refused(f"{name}: {typed!r} is not a number{hint}")
    # A whole number typed as digits is read exactly: a float holds integers only to 2^53, and
    # seeds go to 2^64 - 1.
    value = int(typed) if integer and typed.lstrip("+-").isdigit() else float(typed)
    if not math.isfinite(value):
        raise Refused(f"{name}: {typed!r} is too large")
    if integer and value != int(value):
        raise Refused(f"{name} must be a whole number, got {typed!r}")
    value, message = _clamp(name, value, low, high, unit, above=above, below=below, why=why)
    return (int(value) if integer else value), message


def guarded(callback: Callable[[viser.GuiEvent], None]) -> Callable[[viser.GuiEvent], None]:
    """Wrap a GUI callback: exceptions are logged and shown to the client, never raised into viser."""

    @functools.wraps(callback)
    def wrapper(event: viser.GuiEvent) -> None:
        try:
            callback(event)
        except Refused as exc:
            notify(event.client, "Value refused", str(exc), "warning")
        except Exception as exc:
            log.exception("GUI callback %s failed", callback.__name__)
            notify(event.client, "Something went wrong", f"{type(exc).__name__}: {exc}", "error")

    return wrapper
