"""One exception base: every error class of the product derives from HopperError."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import hopper.app
import hopper.terrain

from hopper.errors import HopperError

# Exceptions used for control flow, not errors a user sees.
NOT_ERRORS = {"hopper.analysis.linearize.Cancelled"}


def product_exceptions() -> list[type[BaseException]]:
    found = []
    # hopper.app and hopper.terrain live in their own folders (pyproject's package-dir): walk each.
    packages = [
        (hopper.__path__, "hopper."),
        (hopper.app.__path__, "hopper.app."),
        (hopper.terrain.__path__, "hopper.terrain."),
    ]
    for info in (i for path, prefix in packages for i in pkgutil.walk_packages(path, prefix)):
        module = importlib.import_module(info.name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, BaseException) and cls.__module__ == info.name:
                found.append(cls)
    return found


def test_every_error_of_ours_is_a_hopper_error_and_keeps_its_standard_base() -> None:
    errors = [c for c in product_exceptions() if f"{c.__module__}.{c.__qualname__}" not in NOT_ERRORS]
    names = {c.__qualname__ for c in errors}
    assert {"InvalidConfig", "SpecError", "KeyframeError", "ViewerError", "Refused", "PortInUse"} <= names, names
    assert [c for c in errors if not issubclass(c, HopperError)] == []
    standard = [c for c in errors if c is not HopperError]
    assert all(any(b.__module__ == "builtins" and b is not object for b in c.__mro__) for c in standard)
    assert all(issubclass(c, Exception) for c in errors)
