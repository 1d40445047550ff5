"""numba's on-disk cache, kept honest: compiled code is dropped when any source it was built from changed."""

from __future__ import annotations

from pathlib import Path

from hopper import stepping
from hopper.control import KERNEL_SOURCES, drop_stale_compiled


def _cache(tmp_path: Path) -> tuple[list[Path], Path, list[Path]]:
    sources = [tmp_path / "kernel.py", tmp_path / "stance.py"]
    for source in sources:
        source.write_text("MIN_SUPPORT = 0.4\n")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    compiled = [cache / "stepping._burst-38.py311.nbi", cache / "stepping._burst-38.py311.1.nbc"]
    return sources, cache, compiled


def test_an_edit_to_a_callee_drops_the_compiled_caller(tmp_path: Path) -> None:
    """hopper.stepping's burst inlines the kernel, and numba reloaded it while stepping.py was
    unchanged: after an edit to stance.py, run() (the burst) and step() flew different robots."""
    sources, cache, compiled = _cache(tmp_path)
    other = cache / "kernel.cpython-311.pyc"
    drop_stale_compiled(sources, cache, "stepping.*.nb[ic]", "stamp")  # the first look: no stamp yet
    for path in (*compiled, other):
        path.write_bytes(b"compiled")
    drop_stale_compiled(sources, cache, "stepping.*.nb[ic]", "stamp")
    assert all(p.exists() for p in compiled)  # nothing changed: numba may load them
    sources[1].write_text("MIN_SUPPORT = 0.45\n")
    drop_stale_compiled(sources, cache, "stepping.*.nb[ic]", "stamp")
    assert not any(p.exists() for p in compiled)
    assert other.exists()  # only what the pattern names


def test_a_cache_that_cannot_be_written_is_left_alone(tmp_path: Path) -> None:
    """An install whose folder cannot be written: numba caches elsewhere; the import must not fail."""
    sources, _, _ = _cache(tmp_path)
    blocked = tmp_path / "a file"
    blocked.write_text("")
    cache = blocked / "__pycache__"  # its parent is a file: no folder can be made there
    drop_stale_compiled(sources, cache, "*.nb[ic]", "stamp")
    assert not cache.exists()


def test_the_kernels_sources_and_the_burst_are_stamped() -> None:
    names = {p.name for p in KERNEL_SOURCES}
    assert {"kernel.py", "stance.py", "legs.py", "memory.py"} <= names
    assert (Path(stepping.__file__).parent / "__pycache__" / "numba-stepping.sha1").exists()
