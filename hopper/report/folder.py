"""A report's folder: what counts as one, and a new report swapped in whole (never a mix of two)."""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shutil
import socket
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


# A staging folder's name after .NAME.partial- (and an earlier report's, moved aside, after .NAME.old-):
# a token, then its writer (pid@host), so that a later run can tell the folders of a writer killed with
# SIGKILL, which nothing could clean up, from a live one's.
WRITER = re.compile(r"[0-9a-f]{8}-(?P<pid>[1-9][0-9]{0,8})@(?P<host>.+)")


@contextlib.contextmanager
def staged(folder: Path) -> Iterator[Path]:
    """A new hidden folder beside `folder` (.NAME.partial-XXXX-PID@HOST) to write a report into. As
    the block ends it takes the place of `folder` whole: what `folder` held (an earlier report) is
    removed only then. If the block raises (a refused input, Ctrl-C), it is removed and `folder` is
    left as it was. OSError, before the block, if it cannot be made: the folder holding `folder` is
    not writable. A symbolic link's folder is the one replaced, the link kept. What killed writers
    left of `folder` is cleared first (remove_stale)."""
    target = folder.resolve()
    remove_stale(target)
    writer = f"{secrets.token_hex(4)}-{os.getpid()}@{socket.gethostname()}"
    partial = target.with_name(f".{target.name}.partial-{writer}")
    partial.mkdir()  # mkdir's mode (umask's), not mkdtemp's 0700: the folder people will open
    try:
        yield partial
        _swap(partial, target, target.with_name(f".{target.name}.old-{writer}"))
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)  # gone already once swapped in
        raise


def remove_stale(folder: Path) -> list[Path]:
    """Clear what writers gone from this host left of `folder` (killed with SIGKILL: nothing could
    clean up): their staging folders are removed, and an earlier report moved aside by a swap the
    kill cut short (.NAME.old-*) is put back if `folder` is missing or empty (it is the only copy),
    removed if `folder` holds a report, and kept otherwise (it may still be the only copy). A
    live writer's folders are kept, as are another host's (a shared disk, where this host cannot
    tell) and an unknown writer's (named otherwise). A pid since reused keeps its folders: never a
    live one's touched. The paths cleared."""
    prefix, host = f".{folder.name}.", socket.gethostname()
    cleared = []
    try:
        siblings = sorted(folder.parent.iterdir())
    except OSError:  # unreadable: staged's own mkdir says what is wrong
        return []
    for path in siblings:
        kind, _, writer = path.name[len(prefix) :].partition("-") if path.name.startswith(prefix) else ("",) * 3
        gone = WRITER.fullmatch(writer) if kind in ("partial", "old") else None
        if not gone or gone["host"] != host or _runs(int(gone["pid"])) or path.is_symlink():
            continue
        if kind == "partial" or is_report_folder(folder):  # a report in place: the copy aside is stale
            shutil.rmtree(path, ignore_errors=True)
        elif _vacant(folder):
            with contextlib.suppress(OSError):  # a live writer raced us to it: it is theirs now
                os.rename(path, folder)  # the earlier report, back where it was
        if not path.exists():
            cleared.append(path)
    return cleared


def _vacant(folder: Path) -> bool:
    """`folder` is missing, or an empty folder (as a command makes for its OUT before it writes):
    removed, so that a copy can take its place."""
    if folder.is_symlink():
        return False
    with contextlib.suppress(OSError):  # missing (or it holds something: then not vacant)
        folder.rmdir()
    return not folder.exists()


def _runs(pid: int) -> bool:
    """A process `pid` exists on this host (a zombie not yet reaped included); True where that cannot
    be asked (not POSIX, where signal 0 is no probe)."""
    if os.name != "posix":
        return True
    try:
        os.kill(pid, 0)  # signal 0: only whether the process exists
    except ProcessLookupError:
        return False
    except OSError:  # EPERM: another user's process, which runs
        return True
    return True


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
