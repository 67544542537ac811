"""The compiled kernels are cached on disk, once per machine, and a change of anything they are built
from (the law, the plant, the kernels) recompiles them (distctrl/batch/jitcache.py)."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip("numba")

from distctrl.batch import closed_loop, jitcache, kernel, soa  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
ENTRY_POINTS = [closed_loop.run_blocks, soa.block_loop, closed_loop.closed_loop, closed_loop._closed_loop_batch,
                kernel.run_setpos_loop, kernel.run_setpos_loop_into, kernel.run_setpos_batch]


@pytest.mark.parametrize("dispatcher", ENTRY_POINTS, ids=lambda d: d.py_func.__name__)
def test_every_kernel_has_the_dependency_keyed_disk_cache(dispatcher):
    assert isinstance(dispatcher._cache, jitcache.KernelCache)
    where = Path(jitcache.cache_dir(dispatcher))
    if os.environ.get("NUMBA_CACHE_DIR"):
        assert str(where).startswith(os.environ["NUMBA_CACHE_DIR"])
    else:     # beside the source, in the folder git ignores
        assert where == Path(dispatcher.py_func.__code__.co_filename).parent / "__pycache__"
        assert "__pycache__/" in (ROOT / ".gitignore").read_text().splitlines()


def test_the_stamp_covers_the_law_the_plant_and_the_kernels(tmp_path, monkeypatch):
    for rel in ("batch/kernel.py", "control/law.py", "sim/physics.py", "errors/__init__.py", "base/states.py",
                "sim/other.py"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(f"# {rel}\n")
    monkeypatch.setattr(jitcache, "_PKG", tmp_path)
    stamp = jitcache.sources_stamp()
    (tmp_path / "sim/other.py").write_text("# not a kernel source\nX = 1\n")
    assert jitcache.sources_stamp() == stamp
    for rel in ("control/law.py", "sim/physics.py", "errors/__init__.py", "base/states.py", "batch/kernel.py"):
        (tmp_path / rel).write_text((tmp_path / rel).read_text() + "X = 2\n")
        new = jitcache.sources_stamp()
        assert new != stamp, rel
        stamp = new


_PROBE = textwrap.dedent("""
    import sys
    from pathlib import Path
    from numba import njit
    from distctrl.batch import jitcache

    jitcache._PKG = Path(sys.argv[1])        # a stand-in for the package: its control/law.py is "the law"

    @jitcache.cached
    @njit(cache=True)
    def kernel(x):
        return x + 1.0

    assert kernel(1.0) == 2.0
    print(kernel.stats.cache_hits and "hit" or "miss", jitcache.is_cached(kernel))
""")


def test_a_second_process_loads_the_kernel_and_a_changed_law_recompiles_it(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "control").mkdir(parents=True)
    (pkg / "control" / "law.py").write_text("K = 1\n")
    probe = tmp_path / "probe.py"
    probe.write_text(_PROBE)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(ROOT))

    def run() -> str:
        proc = subprocess.run([sys.executable, str(probe), str(pkg)], capture_output=True, text=True, env=env,
                              timeout=300)
        assert proc.returncode == 0, proc.stderr
        return proc.stdout.split()[0]

    assert run() == "miss"                                  # compiled, and written to the cache
    assert any(p.suffix == ".nbi" for p in (tmp_path / "cache").rglob("*"))
    assert run() == "hit"                                   # loaded, not compiled
    (pkg / "control" / "law.py").write_text("K = 2\n")        # the law changed
    assert run() == "miss"
    assert run() == "hit"


def test_the_evaluator_says_compiling_only_when_it_compiles(monkeypatch):
    from distctrl.tuning.runner import Evaluator

    from distctrl.batch import warm

    # a command announces the compile once per process (warm.announce_if_cold): an earlier test's
    # command in this process must not count as this evaluator's
    monkeypatch.setitem(warm._STATE, "announced", False)
    inputs = closed_loop.prepare(ROOT / "examples" / "scenarios" / "tune_sheet.toml", 300)
    said: list[str] = []
    with Evaluator(inputs, mode="local", progress=False, log=said.append, cycles=300) as ev:
        monkeypatch.setattr(jitcache, "is_cached", lambda d, argtypes=None: False)
        ev.evaluate([inputs.params])
    assert any(m.startswith("compiling the batch kernels") for m in said), said
    assert any(m.startswith("compiled in") for m in said)
    said.clear()
    monkeypatch.setattr(jitcache, "is_cached", lambda d, argtypes=None: True)
    with Evaluator(inputs, mode="local", progress=False, log=said.append, cycles=300) as ev:
        ev.evaluate([inputs.params])
    assert not any("compiling" in m for m in said), said
