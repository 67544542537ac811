"""The first sweep / tune after installing the extras compiles the batch kernels for 30-80 s: it says so
first, in one line on stderr, never on stdout (new-user audit R17, issue 39), and only then: the line is
said when a kernel the run dispatches is not cached for the argument types it passes, never because of
a kernel it does not run (the SET_POS kernels a sweep leaves uncached). A cold cache is made by telling
the commands which kernels are not cached (the others load from the real cache), and, once, for real: an
empty cache in a temporary copy of the package."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.cli.tune import sweep, tune_cmd  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples" / "scenarios"
LINE = "compiling the batch kernels once for this machine"


def _cold(monkeypatch, which=None):
    """Tell the commands that the kernels ``which`` (default: all) are not cached."""
    import distctrl.batch.jitcache as jc

    real = jc.is_cached
    monkeypatch.setattr(jc, "is_cached", lambda dispatcher, *args: False if which is None or dispatcher in
                        which else real(dispatcher, *args))


def _run(cmd, tmp_path):
    sc = str(EXAMPLES / "tune_sheet.toml")
    if cmd == "sweep":
        return CliRunner().invoke(sweep, [sc, "--grid", "kp=0.3,0.5", "--local", "--out",
                                          str(tmp_path / "s.csv"), "--json"])
    return CliRunner().invoke(tune_cmd, [sc, "--budget", "3", "--local", "--no-robustness", "--out",
                                         str(tmp_path / "t"), "--json"])


@pytest.mark.parametrize("cmd", ["sweep", "tune"])
def test_a_cold_kernel_cache_is_said_first_on_stderr_never_on_stdout(cmd, tmp_path, monkeypatch):
    _cold(monkeypatch)
    sc = str(EXAMPLES / "tune_sheet.toml")
    if cmd == "sweep":
        args = [sc, "--grid", "kp=0.3,0.5", "--local", "--out", str(tmp_path / "s.csv"), "--json"]
        command = sweep
    else:
        args, command = [sc, "--budget", "3", "--local", "--no-robustness", "--out", str(tmp_path / "t"),
                         "--json"], tune_cmd
    res = CliRunner().invoke(command, args)
    assert res.exit_code == 0, res.output
    json.loads(res.stdout)                                   # one object, nothing else
    assert "compiling" not in res.stdout
    lines = [ln for ln in res.stderr.splitlines() if "compiling the batch kernels" in ln]
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("compiling the batch kernels once for this machine (30-80 s")
    assert res.stderr.splitlines()[0] == lines[0]            # first, before the scenario is recorded


@pytest.mark.parametrize("cmd", ["sweep", "tune"])
def test_kernels_the_run_does_not_dispatch_do_not_make_it_say_compiling(cmd, tmp_path, monkeypatch):
    """The audit's re-check: after the first sweep or tune, every later one still said it was compiling
    (and took 2 s), because the SET_POS kernels and the scalar-only loop, which neither runs, stayed
    uncached until ``python -m distctrl.batch.warm``."""
    from distctrl.batch import closed_loop as CL
    from distctrl.batch import kernel as K
    from distctrl.batch.warm import warm

    warm()                                       # the kernels the run needs are cached (or compiled now)
    _cold(monkeypatch, (CL._closed_loop_batch, K.run_setpos_loop, K.run_setpos_loop_into, K.run_setpos_batch))
    res = _run(cmd, tmp_path)
    assert res.exit_code == 0, res.output
    assert LINE not in res.stderr, res.stderr


@pytest.mark.parametrize("which", ["run_blocks", "chunk_metrics"])
def test_a_kernel_the_run_dispatches_uncached_is_said(which, tmp_path, monkeypatch):
    from distctrl.batch import closed_loop as CL
    from distctrl.batch import metrics_kernel as MK

    _cold(monkeypatch, ({"run_blocks": CL.run_blocks, "chunk_metrics": MK.chunk_metrics}[which],))
    res = _run("sweep", tmp_path)
    assert res.exit_code == 0, res.output
    assert [ln for ln in res.stderr.splitlines() if LINE in ln] == [res.stderr.splitlines()[0]], res.stderr


_DISPATCHED = """
import json, sys
from click.testing import CliRunner
from distctrl.cli.tune import sweep, tune_cmd
from distctrl.batch import warm
sc, out = sys.argv[1], sys.argv[2]
res = CliRunner().invoke(sweep, [sc, "--grid", "kp=0.3,0.5", "--local", "--out", out + "/s.csv"])
assert res.exit_code == 0
assert CliRunner().invoke(tune_cmd, [sc, "--budget", "3", "--local", "--out", out + "/t"]).exit_code == 0
print(json.dumps({"dispatched": sorted([d.__name__, str(s)] for d in warm._entries() for s in d.signatures),
                  "asked": sorted([d.__name__, str(s)] for d, s in warm.run_signatures())}))
"""


def test_the_cold_check_asks_for_exactly_the_kernels_and_types_a_sweep_and_a_tune_dispatch(tmp_path):
    """In a fresh process (kernels cached), a sweep and a tune load exactly the signatures
    :func:`distctrl.batch.warm.run_signatures` names: none more (a notice missed), none less (a false one)."""
    from distctrl.batch.warm import warm

    warm()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", _DISPATCHED, str(EXAMPLES / "tune_sheet.toml"),
                           str(tmp_path)], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.splitlines()[-1])
    assert got["dispatched"] == got["asked"]
    assert LINE not in proc.stderr


def test_with_a_real_empty_cache_only_the_first_sweep_says_compiling(tmp_path):
    """The audit's repro, for real: a copy of the package with an empty ``__pycache__``; the first sweep
    compiles and says so, the second loads and says nothing of compiling (it did until the check asked
    only about the kernels the run dispatches). Costs one compile of the sweep's kernels (about 30-60 s)."""
    shutil.copytree(ROOT / "distctrl", tmp_path / "distctrl", ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_CACHE")}
    env["PYTHONPATH"] = str(tmp_path)
    script = "import sys; from distctrl.cli.main import main; sys.exit(main())"
    errs = []
    for k in range(2):
        args = ["sweep", str(EXAMPLES / "tune_sheet.toml"), "--random", "4", "--local", "--out",
                str(tmp_path / f"s{k}.csv")]
        proc = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, env=env,
                              cwd=tmp_path, timeout=900)
        assert proc.returncode == 0, proc.stderr
        errs.append(proc.stderr)
    assert LINE in errs[0], errs[0]
    assert LINE not in errs[1], errs[1]
