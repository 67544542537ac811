"""Short soak and SIGINT-interruption runs (the long soak is ``make stress``: bench/soak.py)."""
from __future__ import annotations

import random

from tests.scripts import load_script

from .conftest import stress_scale, tally

soak_module = load_script("bench/soak.py", "distctrl_bench_soak")


def test_short_soak_no_drift_no_memory_growth_complete_trace():
    cycles = stress_scale(100_000, 1_000_000)
    res = soak_module.soak(cycles, window=10_000, trace_dir=None)
    tally("soak", cycles=res["soak_cycles"], trace_rows=res["soak_trace_rows"])
    assert res["soak_errors"] == []
    assert res["soak_cycles"] >= cycles
    assert res["soak_trace_rows"] == res["soak_cycles"], "the streamed trace lost rows"
    assert res["soak_max_abs_window_mean_error_mm"] <= soak_module.DRIFT_LIMIT_MM
    assert res["soak_offset_drift_first_to_last_window_mm"] <= soak_module.DRIFT_LIMIT_MM
    assert res["soak_rss_max_mb"] <= soak_module.RSS_GROWTH_LIMIT * res["soak_rss_first_window_mb"]
    assert res["soak_pass"]


def test_trace_complete_and_readable_after_sigint(tmp_path):
    rng = random.Random()
    for _ in range(stress_scale(1, 5)):
        r = soak_module.interrupted_run(tmp_path, rng.uniform(1.5, 4.0))
        tally("sigint", runs=1, rows=r["rows"])
        assert r["returncode"] == 130, r["stderr_tail"]
        assert r["rows"] > 0 and r["consecutive"] and r["sidecar"], r
