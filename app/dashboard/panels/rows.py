"""A growing table shown as its newest rows, one HTML element a row: a new row rewrites one element.

viser's HTML element sends its whole content whenever it is set: a table re-rendered at each new
row re-sends every row. Here each shown row is its own element in a fixed ring; a new row takes the
oldest element's place (its content) and moves it to the end, or the top (its order): the other
rows are not sent again. The elements of a table sit in the order band [start, start + BAND) of
their container, so a header, a mean row or a second table can go before or after them.
"""

from __future__ import annotations

import collections

import viser

BAND = 1e12  # orders a table's rows may take (one per row ever added: exact in a float far beyond)


class Rows:
    """The newest `size` rows (HTML, each a whole element) in order band [start, start + BAND)."""

    def __init__(self, gui: viser.GuiApi, size: int, start: float, *, newest_first: bool = False) -> None:
        self._start, self._newest_first = start, newest_first
        self._slots = [gui.add_html("", order=start + i, visible=False) for i in range(size)]
        self._added = 0  # rows added since the last replace: the next row's place in the ring and its order
        self.shown: collections.deque[str] = collections.deque(maxlen=size)  # the rows shown, oldest first

    def add(self, row: str) -> None:
        """Show `row` as the newest; the oldest shown leaves if all `size` are in use."""
        slot = self._slots[self._added % len(self._slots)]
        slot.content = row
        slot.order = self._order(self._added)
        slot.visible = True  # sent only the first time (viser skips a property set to its value)
        self._added += 1
        self.shown.append(row)

    def replace(self, rows: list[str]) -> None:
        """Show exactly the newest of `rows` (oldest first): every element is rewritten (a reset, a restore)."""
        self._added = 0
        self.shown.clear()
        for slot in self._slots:
            slot.visible = False
        for row in rows[-len(self._slots) :]:
            self.add(row)

    def _order(self, n: int) -> float:
        return self._start + (BAND - 1 - n if self._newest_first else 1 + n)
