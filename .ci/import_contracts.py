"""CI: pyproject.toml's import contracts ([tool.importlinter]), checked by lint-imports on the wheel's files.

lint-imports (grimp) finds a package's modules by walking the folders that
`importlib.util.find_spec("hopper").submodule_search_locations` names. In the checkout that is
hopper/ alone: hopper.app and hopper.terrain are the folders app/ and terrain/ (pyproject's
package-dir), which an editable install serves through a meta-path finder that grimp never asks.
So the wheel is built from a clean copy, as .ci/wheel_check.py builds it, unpacked into a
temporary folder (the installed layout: hopper/app/, hopper/terrain/), and lint-imports runs there
with that folder first on sys.path. It reads the files only: nothing is imported or installed.
Exits with lint-imports' status, or 1 saying which step failed. Run as `python .ci/import_contracts.py`.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

from wheel_check import CheckFailed, build_wheel, clean_env  # the same wheel, built the same way

REPO = Path(__file__).resolve().parent.parent
LINT_TIMEOUT_S = 300


def say(message: str) -> None:
    print(f"import contracts: {message}", flush=True)


def unpack(wheel: Path, site: Path) -> None:
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(site)
    for package in ("hopper", "hopper/app", "hopper/terrain"):
        if not (site / package / "__init__.py").is_file():
            raise CheckFailed(f"{package}/__init__.py is not in {wheel.name}")


def check_found_in(site: Path, env: dict[str, str]) -> None:
    """hopper, as lint-imports will find it, is the unpacked wheel's, not the checkout's."""
    code = "import importlib.util; print(*importlib.util.find_spec('hopper').submodule_search_locations)"
    found = subprocess.run(
        [sys.executable, "-c", code], cwd=site, env=env, capture_output=True, text=True, timeout=60, check=True
    ).stdout.split()
    if [Path(p).resolve() for p in found] != [(site / "hopper").resolve()]:
        raise CheckFailed(f"hopper would be read from {found}, not from {site / 'hopper'}")


def lint_imports_script() -> Path:
    script = Path(sys.executable).with_name("lint-imports")  # installed with the test extra
    if not script.is_file():
        raise CheckFailed(f"no {script}: pip install -e '.[test]' installs import-linter")
    return script


def lint_imports(script: Path, site: Path, env: dict[str, str]) -> int:
    try:
        return subprocess.run(
            [script, "--no-cache", "--no-logo", REPO / "pyproject.toml"], cwd=site, env=env, timeout=LINT_TIMEOUT_S
        ).returncode
    except subprocess.TimeoutExpired:
        raise CheckFailed(f"lint-imports took longer than {LINT_TIMEOUT_S} s") from None


def main() -> int:
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="hopper-import-contracts-") as tmp:
        work, site = Path(tmp), Path(tmp) / "site"
        env = {**clean_env(), "PYTHONPATH": str(site)}
        try:
            script = lint_imports_script()
            say("build the wheel")
            wheel = build_wheel(work, clean_env())
            unpack(wheel, site)
            check_found_in(site, env)
            say(f"lint-imports on {wheel.name}, unpacked in {site}")
            status = lint_imports(script, site, env)
        except (CheckFailed, subprocess.CalledProcessError) as exc:
            print(f"import contracts: FAILED: {exc}", file=sys.stderr, flush=True)
            return 1
    say(f"{'kept' if status == 0 else f'BROKEN (lint-imports exited {status})'} in {time.monotonic() - started:.1f} s")
    return status


if __name__ == "__main__":
    sys.exit(main())
