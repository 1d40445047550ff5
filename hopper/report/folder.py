"""A report's folder: what counts as one, and a new report swapped in whole (never a mix of two)."""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import stat
from collections.abc import Iterator
from pathlib import Path

from hopper.interrupts import held

PAGE = "report.html"
FIGURE_SUFFIXES = (".png", ".pdf")


def is_report_folder(folder: Path) -> bool:
    """`folder` holds a report (its report.html) and nothing else than report pages and figures
    (PNG, PDF files): what a new report may replace whole."""
    return (folder / PAGE).is_file() and all(
        p.is_file() and (p.name == PAGE or p.suffix.lower() in FIGURE_SUFFIXES) for p in folder.iterdir()
    )


@contextlib.contextmanager
def staged(folder: Path) -> Iterator[Path]:
    """A new hidden folder beside `folder` (.NAME.partial-XXXX) to write a report into. As the block
    ends it takes the place of `folder` whole: what `folder` held (an earlier report) is removed only
    then. If the block raises (a refused input, Ctrl-C), it is removed and `folder` is left as it
    was. OSError, before the block, if it cannot be made: the folder holding `folder` is not writable.
    A symbolic link's folder is the one replaced, the link kept."""
    target = folder.resolve()
    token = secrets.token_hex(4)
    partial = target.with_name(f".{target.name}.partial-{token}")
    partial.mkdir()  # mkdir's mode (umask's), not mkdtemp's 0700: the folder people will open
    try:
        yield partial
        _swap(partial, target, target.with_name(f".{target.name}.old-{token}"))
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)  # gone already once swapped in
        raise


def _swap(new: Path, folder: Path, old: Path) -> None:
    """`new` renamed to `folder`, what `folder` was moved aside to `old` and removed. A stop signal
    waits for the renames (held): `folder` is the old report or the new one, never missing."""
    with held():
        if folder.exists():
            os.chmod(new, stat.S_IMODE(folder.stat().st_mode))  # its owner's choice of who may read it
            os.rename(folder, old)
        try:
            os.rename(new, folder)
        except BaseException:
            if old.exists():
                os.rename(old, folder)
            raise
        shutil.rmtree(old, ignore_errors=True)
