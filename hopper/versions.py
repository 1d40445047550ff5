"""Release checks for the libraries whose private internals a compat module touches (STYLE.md item 24)."""

from __future__ import annotations

import importlib.metadata

from hopper.errors import HopperError


class UnsupportedVersion(HopperError, RuntimeError):
    """An installed library is outside the release series its compat module was written and tested against."""


def installed_version(distribution: str) -> str:
    """The installed version of a distribution (as pip names it), from its metadata."""
    return importlib.metadata.version(distribution)


def require_series(distribution: str, series: str, found: str, *, module: str) -> None:
    """UnsupportedVersion unless `found` is in the `series` ("1.1": 1.1.0, 1.1.1rc1, 1.1.7, ...).

    `module` is the compat module that asks: the message names it, since that is the file to
    revisit (with its contract tests) before allowing another release.
    """
    if found.split(".")[: series.count(".") + 1] != series.split("."):
        raise UnsupportedVersion(
            f"{distribution} {found} is installed; {module} supports {distribution} {series}.* only "
            f"(it touches private internals of that series; see its contract tests before changing the range)"
        )
