"""hopper-sim's main() in the test's own process (what the process runs, without its start-up cost), and
what a command leaves on disk."""

from __future__ import annotations

from pathlib import Path

import pytest


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """hopper-sim ARGV here: (exit status, stdout, stderr)."""
    from hopper.app.sim_cli import main

    try:
        code = main(list(argv))
    except SystemExit as exc:
        code = int(exc.code)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def tree(folder: Path) -> dict[str, tuple[bytes, float] | None]:
    """Every path under `folder` with its bytes and time of change (None for a folder)."""
    return {
        str(p.relative_to(folder)): None if p.is_dir() else (p.read_bytes(), p.stat().st_mtime)
        for p in sorted(folder.rglob("*"))
    }
