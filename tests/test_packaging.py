"""The package as pip builds and installs it: one import package, its data, its declared dependencies."""

from __future__ import annotations

import ast
import importlib.metadata
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

REPO = Path(__file__).resolve().parent.parent
# Repository folder -> the subpackage it installs as (pyproject.toml's [tool.setuptools] package-dir).
PACKAGE_DIRS = {"hopper": "hopper", "terrain": "hopper/terrain", "app": "hopper/app", "models": "hopper/models"}
PACKAGE_DIRS["static"] = "hopper/static"
ASSETS = ["hopper/models/hopper.xml", *(f"hopper/static/{name}" for name in ("help.md", "dashboard.css", "logo.svg"))]
ASSETS += ["hopper/static/theme.json", "hopper/static/charts.js", "hopper/laws/policy_weights.json"]
# The project's own modules, never from a registry: the package, the benchmarks, and the test
# helpers and test modules that tests import from each other.
# Modules of the package that need an optional extra (and say so when it is missing) -> the extra.
OPTIONAL_EXTRA = {"app/train_policy.py": "rl"}
LOCAL_MODULES = {"hopper", "benchmarks"} | {path.stem for path in (REPO / "tests").glob("*.py")}


# Left-overs of earlier builds: setuptools would pack a stale build/lib into the wheel, hiding a
# subpackage missing from pyproject's list, so the wheel is built from a copy without them.
BUILD_LEFTOVERS = ("build", "dist", "*.egg-info", "__pycache__", ".git", ".*_cache", "sessions", "*.rrd")


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> zipfile.ZipFile:
    source, out = tmp_path_factory.mktemp("source") / "repo", tmp_path_factory.mktemp("wheel")
    shutil.copytree(REPO, source, ignore=shutil.ignore_patterns(*BUILD_LEFTOVERS))
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(out), str(source)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    (built,) = out.glob("hopper_dashboard-*.whl")
    with zipfile.ZipFile(built) as archive:
        yield archive


def test_the_wheel_installs_one_import_package_hopper(wheel: zipfile.ZipFile) -> None:
    top = {name.split("/")[0] for name in wheel.namelist() if not name.split("/")[0].endswith(".dist-info")}
    assert top == {"hopper"}, f"top-level names in the wheel: {sorted(top)}"


def test_the_wheel_holds_the_model_and_the_dashboard_assets(wheel: zipfile.ZipFile) -> None:
    missing = [asset for asset in ASSETS if asset not in wheel.namelist()]
    assert not missing, f"not in the wheel: {missing}"


def test_every_package_and_module_of_the_checkout_is_in_the_wheel(wheel: zipfile.ZipFile) -> None:
    names = set(wheel.namelist())
    assert all((REPO / folder / "__init__.py").is_file() for folder in PACKAGE_DIRS), "layout changed: PACKAGE_DIRS"
    expected = []
    for folder, installed in PACKAGE_DIRS.items():
        for init in (REPO / folder).rglob("__init__.py"):
            package = init.parent.relative_to(REPO / folder)
            expected += [f"{installed}/{package / py.name}" for py in init.parent.glob("*.py")]
    missing = sorted(name for name in expected if name not in names)
    assert not missing, f"in the checkout but not in the wheel (pyproject's packages list?): {missing}"


def _requirement_names(requirements: list[str]) -> set[str]:
    return {_normalize(re.match(r"[A-Za-z0-9._-]+", r).group(0)) for r in requirements}


def _normalize(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _python_files(folders: list[str]) -> list[Path]:
    return [path for folder in folders for path in sorted((REPO / folder).rglob("*.py"))]


def _imported_top_levels(paths: list[Path]) -> dict[str, str]:
    """Top-level modules imported anywhere in `paths` (inside functions too) -> one file importing it."""
    found: dict[str, str] = {}
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules = [node.module]
            else:
                continue
            for module in modules:
                found.setdefault(module.split(".")[0], str(path.relative_to(REPO)))
    return {m: f for m, f in found.items() if m not in sys.stdlib_module_names and m not in LOCAL_MODULES}


def _undeclared(paths: list[Path], declared: set[str]) -> list[str]:
    distributions = importlib.metadata.packages_distributions()
    problems = []
    for module, where in sorted(_imported_top_levels(paths).items()):
        provided_by = {_normalize(d) for d in distributions.get(module, [module])}
        if not provided_by & declared:
            problems.append(f"{module} (imported in {where}, from {sorted(provided_by)})")
    return problems


def test_every_third_party_import_is_a_declared_dependency() -> None:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    runtime = _requirement_names(project["dependencies"])
    test_extra = runtime | _requirement_names(project["optional-dependencies"]["test"])
    optional = [REPO / path for path in OPTIONAL_EXTRA]  # each imports its extra's packages inside main()
    package = [path for path in _python_files(list(PACKAGE_DIRS)) if path not in optional]
    assert _undeclared(package, runtime) == [], "imported at run time but not declared"
    for path, extra in OPTIONAL_EXTRA.items():
        declared = runtime | _requirement_names(project["optional-dependencies"][extra])
        assert _undeclared([REPO / path], declared) == [], f"{path} imports what neither runtime nor [{extra}] declares"
    test_code = _python_files(["tests", "benchmarks"])
    assert _undeclared(test_code, test_extra) == [], "imported by tests or benchmarks but not in the test extra"
