"""Find a controller by its spec and build it with its parameters.

A spec is one of:
- a built-in name: `pid` (the paper's, the default), `lqr`, `mpc`, `policy`;
- `policy:FILE`: the learned law flying the weights in FILE (hopper.laws.policy; `policy` alone: the
  shipped ones). A built-in whose class has `from_file(path)` takes a file this way; the name before
  the colon is the built-in's, never a module's;
- `tcp://127.0.0.1:PORT`: a controller in another process (hopper.laws.remote's protocol);
- `path/to/file.py:ClassName` or `package.module:ClassName`;
- the name of an entry point in the `hopper.controllers` group (an installed package's).

The built-ins load through the same path as a user's class: by their `module:Class` string. A spec
is a string that travels to worker processes, Ray and saved files: every path in it is made
absolute where it is parsed (`canonical`), so that a process started elsewhere finds the same file.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.metadata
import importlib.util
import inspect
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path

from hopper.controllers.api import ControllerError, Param

ENTRY_POINT_GROUP = "hopper.controllers"
BUILTIN = {
    "pid": "hopper.laws.pid:PaperPID",
    "lqr": "hopper.laws.lqr:LQR",
    "mpc": "hopper.laws.mpc:MPC",
    "policy": "hopper.laws.policy:Policy",
}
REMOTE_PREFIX = "tcp://"


def canonical(spec: str) -> str:
    """The spec as every process reads it the same way: a file path made absolute."""
    spec = spec.strip()
    if not spec:
        raise ControllerError("empty controller spec; " + _choices())
    builtin, file = file_argument(spec)
    if file is not None and file.strip():  # none: refused by load_class, as a bad spec is
        return f"{builtin}:{Path(file.strip()).expanduser().resolve()}"
    path, sep, name = spec.rpartition(":")
    if sep and path.endswith(".py") and not spec.startswith(REMOTE_PREFIX):
        return f"{Path(path).expanduser().resolve()}:{name}"
    return spec


def file_argument(spec: str) -> tuple[str, str | None]:
    """(built-in, FILE) for a spec `built-in:FILE` (`policy:weights.json`), else (spec, None)."""
    name, sep, file = spec.partition(":")
    return (name, file) if sep and name in BUILTIN else (spec, None)


def load_class(spec: str) -> type:
    """The controller class a spec names, or ControllerError saying what was wrong and what is allowed.
    A `built-in:FILE` spec's file is read and checked too (`from_file`): refused here, before any work."""
    spec = canonical(spec)
    builtin, file = file_argument(spec)
    if file is not None:
        if not file.strip():
            raise ControllerError(f"{spec!r} names no file: give {builtin}:FILE")
        cls = load_class(builtin)
        from_file = getattr(cls, "from_file", None)
        if from_file is None:
            raise ControllerError(f"{builtin} takes no file after a colon (policy:FILE does: its weights)")
        from_file(file)  # ControllerError in one line: missing, damaged, another layout
        return cls
    if spec.startswith(REMOTE_PREFIX):
        spec = "hopper.laws.remote:RemoteController"
    target = BUILTIN.get(spec) or _entry_point(spec) or spec
    where, sep, name = target.rpartition(":")
    if not sep or not where or not name:
        raise ControllerError(f"unknown controller {spec!r}; " + _choices())
    module = _load_file(where) if where.endswith(".py") else _import(where, spec)
    cls = getattr(module, name, None)
    if cls is None:
        found = sorted(k for k, v in vars(module).items() if inspect.isclass(v) and v.__module__ == module.__name__)
        raise ControllerError(f"{where} has no class {name!r} (classes there: {', '.join(found) or 'none'})")
    if not inspect.isclass(cls):
        raise ControllerError(f"{target} is a {type(cls).__name__}, not a class")
    if not any("__call__" in vars(k) for k in cls.__mro__[:-1]):
        raise ControllerError(f"{target} has no __call__(self, obs) -> float")
    return cls


def declared_params(cls: type) -> tuple[Param, ...]:
    """The class's `params`, each as a Param (a 3- or 4-tuple is accepted), checked."""
    raw = getattr(cls, "params", ())
    owner = cls.__name__
    params: list[Param] = []
    try:
        for item in raw:
            p = item if isinstance(item, Param) else Param(*item)
            low, high = (float(v) for v in p.range)
            p = Param(str(p.name), float(p.default), (low, high), str(p.unit))
            if not p.name.isidentifier() or not low <= p.default <= high:
                raise ValueError(p)
            params.append(p)
    except (TypeError, ValueError) as exc:
        raise ControllerError(
            f"{owner}.params must be Param(name, default, (low, high), unit) entries with low <= default <= high; "
            f"got {exc}"
        ) from None
    return tuple(params)


def build(spec: str, values: Mapping[str, float] | Iterable[tuple[str, float]] = ()) -> object:
    """An instance of the spec's class, its declared params set (defaults, then `values`)."""
    spec = canonical(spec)
    cls = load_class(spec)
    params = {p.name: p for p in declared_params(cls)}
    values = dict(values)
    unknown = sorted(set(values) - set(params))
    if unknown:
        names = ", ".join(params) or "none"
        raise ControllerError(f"{cls.__name__} has no parameter {', '.join(unknown)} (its parameters: {names})")
    try:
        controller = _construct(cls, spec)
    except ControllerError:
        raise
    except Exception as exc:
        raise ControllerError(f"{cls.__name__}() failed: {type(exc).__name__}: {exc}") from exc
    _check_signature(controller, f"{spec}")
    for name, p in params.items():
        setattr(controller, name, p.check(values.get(name, p.default), cls.__name__))
    return controller


def _construct(cls: type, spec: str) -> object:
    """The instance: from the spec's file, with the remote's address, or with no argument."""
    file = file_argument(spec)[1]
    if file is not None:
        return cls.from_file(file)  # type: ignore[attr-defined]
    return cls(spec) if spec.startswith(REMOTE_PREFIX) else cls()


def _choices() -> str:
    names = [*BUILTIN, *(ep.name for ep in _entry_points())]
    return f"choose {', '.join(names)}, policy:FILE, FILE.py:Class, package.module:Class or tcp://127.0.0.1:PORT"


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    return list(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP))


def _entry_point(name: str) -> str | None:
    for ep in _entry_points():
        if ep.name == name:
            return ep.value
    return None


def _import(module: str, spec: str) -> object:
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and module.startswith(exc.name):
            raise ControllerError(f"no module {module!r} for controller {spec!r}; " + _choices()) from None
        raise ControllerError(f"importing {module}: {type(exc).__name__}: {exc}") from exc
    except Exception as exc:
        raise ControllerError(f"importing {module}: {type(exc).__name__}: {exc}") from exc


def _load_file(path: str) -> object:
    """Import a user's file once per process under a name derived from its path."""
    file = Path(path)
    if not file.is_file():
        raise ControllerError(f"controller file {path} does not exist")
    name = "hopper_user_controller_" + hashlib.sha1(str(file).encode()).hexdigest()[:12]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # so that pickling (sweep workers, snapshots) finds its classes
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        del sys.modules[name]
        raise ControllerError(f"controller file {path} failed to load: {type(exc).__name__}: {exc}") from exc
    return module


def _check_signature(controller: object, target: str) -> None:
    """`controller(obs)` and, if it has one, `controller.reset(obs)` each take exactly one argument
    (bound methods: a staticmethod, a classmethod or a plain function attribute pass as well)."""
    for method in ("__call__", "reset"):
        fn = getattr(controller, method, None)
        if fn is None:
            continue
        try:
            signature = inspect.signature(fn)
        except (TypeError, ValueError):
            continue  # a builtin without a signature: tried at the first call instead
        try:
            signature.bind(None)
        except TypeError:
            name = type(controller).__name__
            raise ControllerError(f"{target}: {name}.{method} must take (self, obs); it takes {signature}") from None
