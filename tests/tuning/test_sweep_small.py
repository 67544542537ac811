"""A sweep that fits in one chunk runs in this process: the embedded cluster could not spread one chunk
over its workers and would only add its start-up (issue 13: the second sweep call within 2 s)."""
from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from distctrl.cli import main

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def test_a_one_chunk_sweep_runs_in_this_process_and_says_so(tmp_path):
    res = CliRunner().invoke(main, ["sweep", str(SCN / "tune_sheet.toml"), "--random", "4", "--cycles", "300",
                                    "--out", str(tmp_path / "s.csv"), "--json"])
    assert res.exit_code == 0, res.output
    js = json.loads(res.stdout)
    assert js["mode"] == "local" and js["sets"] == 4
    assert "fit in one chunk: running in this process" in res.stderr


def test_a_sweep_takes_what_it_has_loaded_out_of_the_collector_s_scans_before_the_kernels_load(tmp_path,
                                                                                            monkeypatch):
    """The command's modules, numba and the recorded scenario live until the process ends; every full
    collection of Python's cyclic garbage collector walked them all again, and a sweep spent about 0.2 s of
    its 1 s start in it while numba loaded the cached kernels (bench/bench_sweep.py's fixed cost, issue 27).
    The command freezes them (gc.freeze) before the kernels load."""
    import gc

    from distctrl.tuning.runner import Evaluator

    order = []
    frozen_before = gc.get_freeze_count()
    real_freeze, real_prepare = gc.freeze, Evaluator.prepare_kernels
    monkeypatch.setattr(gc, "freeze", lambda: (order.append("freeze"), real_freeze()))
    monkeypatch.setattr(Evaluator, "prepare_kernels",
                        lambda self, *a, **k: (order.append("kernels"), real_prepare(self, *a, **k))[1])
    try:
        res = CliRunner().invoke(main, ["sweep", str(SCN / "tune_sheet.toml"), "--random", "4", "--cycles", "300",
                                        "--local", "--out", str(tmp_path / "s.csv"), "--json"])
        assert res.exit_code == 0, res.output
        assert "freeze" in order and "kernels" in order, order
        assert order.index("freeze") < order.index("kernels"), order
        assert gc.get_freeze_count() > frozen_before
    finally:
        gc.unfreeze()                   # this test process's objects go back to the collector
