"""A typed number: a text box read on the server after a quiet time, never keystroke by keystroke.

viser's number boxes (Mantine NumberInput) filter keys in the browser and send every keystroke:
"1e9" arrives as 1 then 19, "1,5" as 15, "abc" or "NaN" empties the box and sends nothing, and
typing 800 sends 8, 80, 800. So the text goes to the server as typed and is checked there.
A slider keeps its drag; its own box is hidden (`hide_slider_boxes`) and a NumberEntry goes beside it.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping

import viser
from hopper.app.dashboard import viser_compat as compat
from hopper.app.dashboard.feedback import Refused, format_number, notify, parse_number

log = logging.getLogger(__name__)

QUIET_S = 0.5  # s without a keystroke before typed text is applied
# Text that ends like this is a number being typed ("0.", "1e", "-"): applied only after a longer
# pause, so that a slow typist's "0." is not clamped and rewritten before the 5 arrives. So is
# the start of a word the box takes ("ma" of "max").
UNFINISHED = (".", "e", "E", "+", "-")
UNFINISHED_QUIET_S = 3.0

Apply = Callable[[float, "viser.ClientHandle | None"], None]


class NumberEntry:
    """One number typed in a text box; the box always shows the value in use.

    After QUIET_S without typing (or at once through `commit`, e.g. when a button needs the
    value), the text is parsed: text that is not a number is refused with a notification and the
    box shows the value in use again; a number out of [low, high] is clamped, with a notification
    that gives the range and units. `on_apply(value, client)` then receives the new value (on a
    timer or viser thread: it must only validate and queue). `words` name values that are no
    number in range (Speed's Max): the box shows the word and takes it typed, in any case.
    `above` / `below` exclude low / high (refused, not clamped: no nearest number is in range);
    `why` names what sets high (a notice says it). With `magnitude`, a negative number is taken
    as its size (Back: "-5" and "5" both mean 5 s ago; the box then shows 5).
    """

    def __init__(
        self,
        handle: viser.GuiTextHandle,
        name: str,
        low: float,
        high: float,
        unit: str = "",
        *,
        value: float,
        integer: bool = False,
        on_apply: Apply | None = None,
        quiet_s: float = QUIET_S,
        words: Mapping[str, float] | None = None,
        above: bool = False,
        below: bool = False,
        why: str = "",
        magnitude: bool = False,
    ) -> None:
        self.handle, self.name, self.low, self.high, self.unit = handle, name, low, high, unit
        self.integer, self.on_apply, self.quiet_s = integer, on_apply, quiet_s
        self.above, self.below, self.why = above, below, why
        self.words = dict(words or {})
        self.magnitude = magnitude
        self._value = value
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None
        self._client: viser.ClientHandle | None = None
        handle.value = self.text(value)
        handle.on_update(self._typed)

    @property
    def value(self) -> float:
        """The value in use (what the box shows once typing has stopped)."""
        return self._value

    def show(self, value: float) -> None:
        """Keep and show a value set by the program (a slider, a reset); no notification, no on_apply."""
        with self._lock:
            self._value = value
            self.handle.value = self.text(value)  # its own update event has no client: ignored

    def close(self) -> None:
        """Drop typing not yet applied and apply nothing more (the box is being removed)."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
            self.on_apply = None

    def commit(self, client: viser.ClientHandle | None = None) -> float | None:
        """Apply what is typed now; the value in use, or None if the text was refused (and notified)."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
            client = client or self._client
            text = self.handle.value
            if text == self.text(self._value):
                return self._value
            try:
                value, message = self._parse(text)
            except Refused as exc:
                self.handle.value = self.text(self._value)
                kept = self.text(self._value)
                if self.unit and self._value not in self.words.values():
                    kept += f" {self.unit}"
                refusal = f"{exc}; kept {kept}"
            else:
                refusal = None
                changed = value != self._value
                self._value = value
                self.handle.value = self.text(value)
        if refusal is not None:
            notify(client, "Value refused", refusal, "warning")
            return None
        if message:
            notify(client, "Value clamped", message, "warning")
        if changed and self.on_apply is not None:
            self.on_apply(value, client)
        return value

    def text(self, value: float) -> str:
        """What the box shows for `value`: its word, if it has one, or the number."""
        return next((word for word, named in self.words.items() if named == value), None) or format_number(value)

    def _parse(self, text: str) -> tuple[float, str | None]:
        """Typed text as (value, clamp message): a word, or a number (Refused: why not)."""
        for word, value in self.words.items():
            if text.strip().lower() == word.lower():
                return value, None
        if self.magnitude and text.strip().startswith("-"):
            text = text.strip()[1:]
        try:
            return parse_number(
                self.name,
                text,
                self.low,
                self.high,
                self.unit,
                integer=self.integer,
                above=self.above,
                below=self.below,
                why=self.why,
            )
        except Refused as exc:
            if not self.words:
                raise
            raise Refused(f"{exc} (or {' / '.join(self.words)})") from None

    def _unfinished(self, text: str) -> bool:
        """Whether `text` looks half typed: a number ("1e", "-") or the start of a word ("ma")."""
        typed = text.lower()
        starts = [word.lower() for word in self.words if word.lower().startswith(typed)]
        return text.endswith(UNFINISHED) or bool(typed and starts and typed not in starts)

    def _typed(self, event: viser.GuiEvent) -> None:
        if event.client is None:  # the program's own assignment, not typing
            return
        with self._lock:
            self._client = event.client
            if self._timer is not None:
                self._timer.cancel()
            wait = self.quiet_s
            if self._unfinished(self.handle.value.strip()):
                wait = max(wait, UNFINISHED_QUIET_S)
            self._timer = threading.Timer(wait, self._quiet)
            self._timer.daemon = True
            self._timer.start()

    def _quiet(self) -> None:
        client = self._client
        try:
            self.commit()
        except Exception as exc:  # a timer thread has nobody to report to but the typist
            log.exception("applying %s failed", self.name)
            notify(client, "Something went wrong", f"{type(exc).__name__}: {exc}", "error")


def hide_slider_boxes(gui: viser.GuiApi, sliders: list[viser.GuiSliderHandle[float]]) -> viser.GuiHtmlHandle:
    """Hide the number box viser draws beside each slider: it has the faults NumberEntry avoids.

    viser gives a slider's root element the handle's id and draws the box right after it (no
    option of add_slider leaves it out). Returns the style's element (remove it with the sliders).
    """
    selectors = ", ".join(f'[id="{compat.element_id(s)}"] + .mantine-NumberInput-root' for s in sliders)
    return gui.add_html(f"<style>{selectors} {{ display: none; }}</style>")
