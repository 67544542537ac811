"""Traces cannot fill the disk or the memory: the ring buffer (max_rows), the thinned keep
(keep_at_most) and a file error that names its path (issue 13, docs/trace.md)."""
from __future__ import annotations

import errno
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.trace import Trace, TraceRecorder

COLS = ["t", "v"]


def _record(n: int, **kw) -> TraceRecorder:
    rec = TraceRecorder(COLS, {"t": "s"}, chunk_rows=kw.pop("chunk_rows", 7), **kw)
    for i in range(n):
        rec.append((float(i), 2.0 * i))
    return rec


@given(n=st.integers(0, 300), max_rows=st.integers(1, 50), chunk=st.integers(1, 40))
@settings(max_examples=60, deadline=None)
def test_the_ring_buffer_keeps_exactly_the_last_rows(n, max_rows, chunk):
    rec = _record(n, max_rows=max_rows, chunk_rows=chunk)
    tr = rec.close()
    expect = np.arange(max(0, n - max_rows), n, dtype=float)
    assert np.array_equal(tr["t"], expect) and np.array_equal(tr["v"], 2.0 * expect)
    assert tr.meta["dropped_rows"] == max(0, n - max_rows) and tr.meta["ring_buffer_rows"] == max_rows


def test_the_ring_buffer_writes_its_rows_to_the_csv_at_the_end(tmp_path):
    path = tmp_path / "scope.csv"
    rec = _record(1000, max_rows=64, csv_path=path, keep=False)
    assert rec.close() is None
    back = Trace.from_csv(path)
    assert back.rows == 64 and back["t"][0] == 936.0 and back["t"][-1] == 999.0
    assert back.meta["dropped_rows"] == 936


@given(n=st.integers(0, 2000), limit=st.integers(2, 100), chunk=st.integers(1, 64))
@settings(max_examples=60, deadline=None)
def test_the_thinned_keep_is_every_stride_th_row_and_never_more_than_the_limit(n, limit, chunk):
    rec = _record(n, keep_at_most=limit, chunk_rows=chunk)
    tr = rec.close()
    stride = rec.stride
    assert tr.rows <= limit
    assert np.array_equal(tr["t"], np.arange(0, n, stride, dtype=float))
    assert stride == 1 or n > limit                          # thinned only when it had to be
    if stride > 1:
        assert tr.meta["kept_every"] == stride


def test_thinning_the_kept_trace_leaves_the_csv_whole(tmp_path):
    path = tmp_path / "t.csv"
    tr = _record(5000, keep_at_most=100, csv_path=path).close()
    assert tr.rows <= 100 and Trace.from_csv(path).rows == 5000


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_full_disk_is_an_oserror_naming_the_trace():
    with pytest.raises(OSError) as info:
        TraceRecorder(COLS, csv_path="/dev/full")
    assert info.value.errno == errno.ENOSPC and info.value.filename == "/dev/full"
