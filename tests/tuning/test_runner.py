"""Chunked evaluation: local and on an embedded dask LocalCluster give identical results; retries."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

from distctrl.batch.closed_loop import prepare, run_batch  # noqa: E402
from distctrl.tuning.metrics import METRIC_NAMES  # noqa: E402
from distctrl.tuning.runner import Evaluator, TuningRunError, evaluate_chunk, plot_sweep  # noqa: E402
from distctrl.tuning.space import build_sets, grid_points, parse_grid  # noqa: E402

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml"
CYCLES = 2000


@pytest.fixture(scope="module")
def inputs():
    return prepare(SCN, CYCLES)


@pytest.fixture(scope="module")
def sets(inputs):
    pts = grid_points(parse_grid("kp=0.2:1.6:4,d_tv=0,0.004,filter_type=MOVING_AVERAGE,n_cycles=2,8"))
    s, pts, rej = build_sets(inputs.params, pts, inputs.cycle_time)
    assert len(s) == 16 and not rej
    return s, pts


@pytest.fixture(scope="module")
def local_result(inputs, sets):
    with Evaluator(inputs, mode="local", chunk_size=5, progress=False) as ev:
        return ev.evaluate(*sets)


def test_local_matches_direct_kernel(inputs, sets, local_result):
    offset, distance = run_batch(inputs, sets[0])
    e = distance[:, inputs.k_on:] - inputs.set_value
    assert np.allclose(local_result["rms_error"], np.sqrt(np.mean(e ** 2, axis=1)), rtol=0, atol=1e-12)
    assert len(local_result) == 16 and local_result.info["cycles"] == CYCLES


def test_cluster_identical_and_dask_retry(inputs, sets, local_result, tmp_path):
    pytest.importorskip("distributed")
    flag = tmp_path / "failed-once"

    def flaky(slim, packed, cycles, opts, threads):     # pickled by value (a closure)
        import os
        if not os.path.exists(flag):
            open(flag, "w").close()
            raise RuntimeError("simulated chunk failure")
        from distctrl.tuning.runner import evaluate_chunk as ec
        return ec(slim, packed, cycles, opts, threads)

    with Evaluator(inputs, mode="cluster", n_workers=2, chunk_size=4, progress=False) as ev:
        res = ev.evaluate(*sets)
        ev.chunk_fn = flaky
        res2 = ev.evaluate(*sets)
    for name in METRIC_NAMES + ("cost",):
        assert np.array_equal(res[name], local_result[name], equal_nan=True), name
        assert np.array_equal(res2[name], local_result[name], equal_nan=True), name
    assert flag.exists()
    assert res.info["workers"] == 2


def test_local_retry_and_give_up(inputs, sets, local_result):
    calls = {"n": 0}

    def flaky(*args):
        calls["n"] += 1
        if calls["n"] == 1:
            raise RuntimeError("simulated chunk failure")
        return evaluate_chunk(*args)

    with Evaluator(inputs, mode="local", chunk_size=8, progress=False, chunk_fn=flaky) as ev:
        res = ev.evaluate(*sets)
        assert ev.stats["retried"] == 1
    assert np.array_equal(res["rms_error"], local_result["rms_error"])

    def broken(*args):
        raise RuntimeError("always")

    with Evaluator(inputs, mode="local", retries=1, progress=False, chunk_fn=broken) as ev:
        with pytest.raises(TuningRunError, match="failed after 1 retries"):
            ev.evaluate(*sets)


def test_write_csv_parquet_and_plots(local_result, tmp_path):
    import csv
    p = local_result.write(tmp_path / "r.csv")
    rows = list(csv.DictReader(open(p)))
    assert len(rows) == 16 and {"kp", "rms_error", "sat_share", "error_id"} <= set(rows[0])
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    t = pq.read_table(local_result.write(tmp_path / "r.parquet"))
    assert t.num_rows == 16 and np.allclose(t.column("rms_error").to_numpy(), local_result["rms_error"])
    plot_sweep(local_result, tmp_path / "heat.png")                    # kp x n_cycles heatmap
    assert (tmp_path / "heat.png").stat().st_size > 1000
    assert "kp" in local_result.render(3, plain=True)


def test_cluster_worker_killed_mid_sweep_loses_only_its_chunk(inputs, sets, local_result, tmp_path):
    """A worker process dies (os._exit) while running one chunk: dask reschedules that chunk on the
    restarted worker, the sweep completes with the same numbers, and the chunks already fetched are
    not run again. One worker, so the dying process ran every other chunk: without the release on
    fetch dask would recompute them."""
    pytest.importorskip("distributed")
    log = tmp_path / "calls.log"
    killed = tmp_path / "killed"
    done = tmp_path / "done.keys"                       # the task keys of the chunks that finished
    victim = 3                                          # the last chunk of four sets

    def dying(slim, packed, cycles, opts, threads):     # pickled by value (a closure)
        import os
        import time
        import numpy as np
        from distributed import get_client, get_worker, secede
        chunk = int(np.argmin(np.abs(all_first - packed[0]).sum(axis=1)))
        me = get_worker().get_current_task()
        with open(log, "a") as f:
            f.write(f"{chunk} {os.getpid()}\n")
        if chunk == victim and not os.path.exists(killed):
            # leave the worker's only thread to the other three chunks (secede), wait until all of
            # them finished on this worker and were fetched by the Evaluator, then die. It releases
            # each result as it fetches it and the scheduler then forgets that task, so waiting on
            # the scheduler's state (not on a sleep) keeps the test free of timing races
            secede()
            client = get_client()

            def held(dask_scheduler):
                return sum(1 for k in dask_scheduler.tasks if str(k) in finished)

            deadline = time.monotonic() + 120
            while time.monotonic() < deadline:
                finished = set(done.read_text().split()) if done.exists() else set()
                if len(finished) == 3 and not client.run_on_scheduler(held):
                    break
                time.sleep(0.02)
            killed.write_text(str(len(finished)))
            os._exit(1)                                 # the worker process dies, no exception
        from distctrl.tuning.runner import evaluate_chunk as ec
        result = ec(slim, packed, cycles, opts, threads)
        with open(done, "a") as f:
            f.write(f"{me}\n")
        return result

    from distctrl.batch.closed_loop import pack_sets
    all_first = pack_sets(inputs, sets[0])[::4]         # first row of every chunk
    with Evaluator(inputs, mode="cluster", n_workers=1, chunk_size=4, progress=False, chunk_fn=dying) as ev:
        res = ev.evaluate(*sets)
    assert len(done.read_text().split()) == 4
    assert int(killed.read_text()) == 3       # the three other chunks had run on the dying worker
    for name in METRIC_NAMES + ("cost",):
        assert np.array_equal(res[name], local_result[name], equal_nan=True), name
    calls = [line.split() for line in log.read_text().split("\n") if line]
    runs = {c: [pid for cc, pid in calls if int(cc) == c] for c in range(4)}
    assert len(runs[victim]) == 2 and runs[victim][0] != runs[victim][1], runs   # lost once, rerun on the new process
    # the chunks fetched before the death were released at once, so none of them runs again
    # (without the release, those held by the dying worker would be recomputed)
    assert all(len(r) == 1 for c, r in runs.items() if c != victim), runs


def test_a_chunk_runs_its_metrics_pass_on_the_chunks_threads_too(monkeypatch):
    """The metrics pass is parallel over the sets (numba threads): a worker's chunk (threads=1) must not
    start more threads than the worker has (issue 27)."""
    numba = pytest.importorskip("numba")
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one numba thread only")
    from distctrl.batch import closed_loop as CL
    from distctrl.tuning import runner

    inputs = CL.prepare(SCN, cycles=300)
    seen = []
    real = runner.compute_metrics

    def spy(*a, **k):
        seen.append(numba.get_num_threads())
        return real(*a, **k)
    monkeypatch.setattr(runner, "compute_metrics", spy)
    before = numba.get_num_threads()
    runner.evaluate_chunk(runner.slim_inputs(inputs), CL.pack_sets(inputs, [inputs.params] * 2), None, {}, 1)
    assert seen == [1]
    assert numba.get_num_threads() == before


def _points_case(inputs):
    from distctrl.tuning.columns import columns_of, drop_inert_columns, random_columns

    pc, _ = drop_inert_columns(random_columns(700, 11, cycle_time=inputs.cycle_time))
    grid = columns_of(grid_points(parse_grid("kp=0.3,1.2,filter_type=LOWPASS,order=1,4,fg_f0=100,800")))
    return pc, grid


def _same_tables(a, b):
    assert a.columns == b.columns
    for c in a.columns:
        x, y = a[c], b[c]
        if isinstance(x, list) or isinstance(y, list):
            assert list(x) == list(y), c
        else:
            assert x.dtype == y.dtype, c
            assert np.array_equal(x, y, equal_nan=True), c


def test_evaluate_points_checks_packs_and_runs_in_the_chunks_and_gives_evaluates_table(inputs, monkeypatch):
    """Issue 27: the chunks get points (columns), not packed rows, and check, design and pack them
    themselves; the table is that of build_sets + evaluate, the rejected points and messages too."""
    from distctrl.tuning import runner

    seen = []
    real = runner.evaluate_points_chunk

    def spy(inputs_, chunk, *a, **k):
        assert not any(isinstance(v, np.ndarray) and v.ndim == 2 for v in vars(chunk).values())
        assert chunk.block == 128
        seen.append(len(chunk))
        return real(inputs_, chunk, *a, **k)
    monkeypatch.setattr(runner, "evaluate_points_chunk", spy)
    for pc in _points_case(inputs):
        sets, pts, rejected = build_sets(inputs.params, pc.to_points(), inputs.cycle_time)
        with Evaluator(inputs, mode="local", chunk_size=128, progress=False) as ev:
            want = ev.evaluate(sets, pts)
            seen.clear()
            got = ev.evaluate_points(inputs.params, pc)
        assert sum(seen) == pc.n and (pc.n <= 128 or len(seen) > 1)
        assert got.rejected == rejected
        _same_tables(got, want)


def test_evaluate_points_on_a_cluster_gives_the_local_table(inputs):
    pytest.importorskip("distributed")
    pc, grid = _points_case(inputs)
    with Evaluator(inputs, mode="local", chunk_size=256, progress=False) as ev:
        want = ev.evaluate_points(inputs.params, pc)
    with Evaluator(inputs, mode="cluster", n_workers=2, chunk_size=256, progress=False) as ev:
        got = ev.evaluate_points(inputs.params, pc)
        assert ev.stats["kernel_s"] > 0 and ev.stats["task_s"] >= ev.stats["kernel_s"]
    _same_tables(got, want)


def test_evaluate_points_checks_the_next_chunk_ahead_and_gives_the_same_table(inputs, monkeypatch):
    """In this process the next chunk's points are checked in a second thread while one chunk runs
    (Evaluator._run_local's ``ahead``): the same table, the same rejected points, as checking each chunk
    in its own task."""
    from distctrl.tuning import runner
    from distctrl.tuning.columns import drop_inert_columns, random_columns

    pc, _ = drop_inert_columns(random_columns(300, 4, cycle_time=inputs.cycle_time))
    pc.cols["kp"][::7] = 50.0                                        # out of range: rejected, in order
    handed = []
    real = runner.evaluate_points_chunk

    def chunk_fn(*a, checked=None, **k):
        handed.append(checked is not None)
        return real(*a, checked=checked, **k)
    monkeypatch.setattr(runner, "evaluate_points_chunk", chunk_fn)
    monkeypatch.setattr(runner, "_side_by_side_cores", lambda: 1)     # one chunk after the other
    with Evaluator(inputs, mode="local", chunk_size=16, progress=False) as ev:
        ahead = ev.evaluate_points(inputs.params, pc)
        assert len(handed) > 1 and all(handed)                       # every chunk came checked
        handed.clear()
        monkeypatch.setattr(ev, "_run_local", _without_ahead(ev._run_local))
        alone = ev.evaluate_points(inputs.params, pc)
        assert handed and not any(handed)
    _same_tables(ahead, alone)
    assert [m for _, m in ahead.rejected] == [m for _, m in alone.rejected] and ahead.rejected
    assert np.array_equal(ahead.info["kept"], alone.info["kept"])


def _without_ahead(run_local):
    def run(chunks, description, fn=None, extra=None, ahead=None, options=None):
        return run_local(chunks, description, fn, extra, options=options)
    return run


def test_a_chunk_whose_check_ahead_fails_is_run_whole(inputs, monkeypatch):
    """An exception in the check ahead is not the sweep's end: the chunk's own task checks again (and
    would report what is wrong)."""
    from distctrl.tuning import runner
    from distctrl.tuning.columns import drop_inert_columns, random_columns

    pc, _ = drop_inert_columns(random_columns(64, 5, cycle_time=inputs.cycle_time))
    real = runner.check_points_chunk
    monkeypatch.setattr(runner, "check_points_chunk", _failing_on_call(real, 2, "check ahead lost"))
    monkeypatch.setattr(runner, "_side_by_side_cores", lambda: 1)
    with Evaluator(inputs, mode="local", chunk_size=16, progress=False) as ev:
        got = ev.evaluate_points(inputs.params, pc)
    monkeypatch.setattr(runner, "check_points_chunk", real)
    with Evaluator(inputs, mode="local", chunk_size=16, progress=False) as ev:
        want = ev.evaluate_points(inputs.params, pc)
    _same_tables(got, want)


def test_chunks_side_by_side_give_the_table_of_chunks_in_turn(inputs, monkeypatch):
    """Where numba runs parallel kernels from several threads (tbb, omp), a local sweep runs one chunk per
    core, each on one numba thread: the same table, the same rejected points, as one chunk after the other."""
    import numba

    from distctrl.tuning import runner
    from distctrl.tuning.columns import drop_inert_columns, random_columns

    run_batch(inputs, inputs_packed_one(inputs), cycles=8)          # a parallel kernel ran: the layer is known
    pc, _ = drop_inert_columns(random_columns(300, 6, cycle_time=inputs.cycle_time))
    pc.cols["kp"][::11] = 50.0
    cores = runner._side_by_side_cores
    used = []
    real = runner.ThreadPoolExecutor

    def pool(n, thread_name_prefix=""):
        used.append(thread_name_prefix)
        return real(n, thread_name_prefix=thread_name_prefix)
    monkeypatch.setattr(runner, "ThreadPoolExecutor", pool)
    monkeypatch.setattr(runner, "_side_by_side_cores", lambda: 2)
    with Evaluator(inputs, mode="local", chunk_size=16, progress=False) as ev:
        side = ev.evaluate_points(inputs.params, pc)
    assert "distctrl-chunk" in used
    monkeypatch.setattr(runner, "_side_by_side_cores", lambda: 1)
    used.clear()
    with Evaluator(inputs, mode="local", chunk_size=16, progress=False) as ev:
        turn = ev.evaluate_points(inputs.params, pc)
    assert "distctrl-chunk" not in used
    _same_tables(side, turn)
    assert [m for _, m in side.rejected] == [m for _, m in turn.rejected] and side.rejected
    if numba.threading_layer() in ("tbb", "omp"):
        assert cores() == numba.get_num_threads()
    else:
        assert cores() == 1


def test_a_failing_chunk_side_by_side_is_retried_then_reported(inputs, monkeypatch):
    from distctrl.tuning import runner
    from distctrl.tuning.columns import drop_inert_columns, random_columns

    pc, _ = drop_inert_columns(random_columns(64, 7, cycle_time=inputs.cycle_time))
    monkeypatch.setattr(runner, "_side_by_side_cores", lambda: 2)
    monkeypatch.setattr(runner, "evaluate_points_chunk", _failing_on_call(runner.evaluate_points_chunk, 1, "lost"))
    with Evaluator(inputs, mode="local", chunk_size=16, progress=False) as ev:
        got = ev.evaluate_points(inputs.params, pc)
        assert ev.stats["retried"] == 1
    monkeypatch.setattr(runner, "evaluate_points_chunk", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("gone")))
    with Evaluator(inputs, mode="local", chunk_size=16, progress=False, retries=1) as ev:
        with pytest.raises(TuningRunError, match="failed after 1 retries: RuntimeError: gone"):
            ev.evaluate_points(inputs.params, pc)
    assert len(got) == 64


def _failing_on_call(real, k: int, message: str):
    """``real``, but its k-th call raises RuntimeError(message)."""
    calls = []

    def flaky(*a, **kw):
        calls.append(1)
        if len(calls) == k:
            raise RuntimeError(message)
        return real(*a, **kw)
    return flaky


def inputs_packed_one(inputs):
    from distctrl.batch.closed_loop import pack_sets

    return pack_sets(inputs, [inputs.params])


def test_the_embedded_cluster_runs_without_the_dashboard_s_high_rate_timers(inputs):
    """The embedded LocalCluster's processes share the machine's cores with the chunks: dask's 20 ms event-loop
    tick, the workers' 10 ms statistical profiler and the 100-500 ms monitors kept the two workers and the
    scheduler at about 1 CPU-s per 10 s while idle, and made each task about 7 % slower with 2 workers on 2
    cores (bench/bench_sweep.py's dask scaling, issue 27). The workers (spawned processes) and the scheduler
    run with the slower timers of runner.EMBEDDED_CLUSTER_CONFIG; the caller's dask config is left as it was."""
    pytest.importorskip("distributed")
    import dask

    from distctrl.tuning import runner

    keys = ("distributed.worker.profile.enabled", "distributed.admin.tick.interval",
            "distributed.admin.system-monitor.interval", "distributed.worker.memory.monitor-interval")
    before = {k: dask.config.get(k) for k in keys}
    assert before["distributed.worker.profile.enabled"] is True          # dask's defaults in this process
    with Evaluator(inputs, mode="cluster", n_workers=1, progress=False) as ev:
        ev.open()
        seen = ev._client.run(lambda: {k: dask.config.get(k) for k in keys})
        tick = ev._client.run_on_scheduler(lambda dask_scheduler: dask_scheduler._tick_interval)
        assert {k: dask.config.get(k) for k in keys} == before            # not changed for the caller
    (worker,) = seen.values()
    assert worker["distributed.worker.profile.enabled"] is False
    for k in keys[1:]:
        assert dask.utils.parse_timedelta(worker[k]) >= 0.5, (k, worker[k])
    assert tick >= 0.5
    assert worker == {k: runner.EMBEDDED_CLUSTER_CONFIG.get(k, before[k]) for k in keys}


@pytest.mark.parametrize("n,block,parts,side", [(10000, 256, 8, 2), (9992, 256, 8, 2), (10000, 256, 8, 3),
                                                (10**6, 256, 16, 2), (300, 256, 8, 2), (10, 256, 8, 2),
                                                (10000, 256, 8, 1), (5000, 7, 8, 4)])
def test_chunks_cover_the_points_in_order_and_side_by_side_threads_end_them_apart(n, block, parts, side):
    """chunk_bounds: the chunks are the points in order, each at most MAX_TASK_BLOCKS blocks. Run side by side
    (each thread takes the next chunk when it is free, a chunk's time its length), no two threads end a chunk
    at the same time before the last ones: at its end a chunk formats its rows and the next one checks its
    points, Python that holds the GIL, and threads there at once waited for each other."""
    from distctrl.tuning.runner import MAX_TASK_BLOCKS, chunk_bounds

    bounds = chunk_bounds(n, block, parts, side)
    assert bounds[0][0] == 0 and bounds[-1][1] == n
    assert all(a < b for a, b in bounds) and all(b == a2 for (_, b), (a2, _) in zip(bounds, bounds[1:]))
    assert max(b - a for a, b in bounds) <= max(block, MAX_TASK_BLOCKS * block)
    if side == 1 or len(bounds) < 2 * side:
        return
    free = [0.0] * side                      # when each thread is free; it takes the next chunk
    ends = []
    for a, b in bounds:
        t = min(range(side), key=lambda i: free[i])
        free[t] += b - a
        ends.append(free[t])
    size = bounds[0][1] - bounds[0][0]
    inner = sorted(ends[:-side])             # the threads' last chunks may end together
    assert all(y - x >= size // side - 1 for x, y in zip(inner, inner[1:])), inner
