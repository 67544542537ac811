"""TraceRecorder and Trace: exact CSV round trips, chunking, streaming, sidecar, close, speed."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from distctrl.trace import Trace, TraceRecorder, sidecar_path

COLS = ["t", "line", "Z.prog", "Z.cmd", "Z.act", "Z.dc.state", "Z.dc.offset", "true.surface",
        "true.distance"]
UNITS = {"t": "s", "Z.prog": "mm", "Z.cmd": "mm", "Z.act": "mm", "Z.dc.offset": "mm",
         "true.surface": "mm", "true.distance": "mm"}


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        return False
    nan = np.isnan(a) & np.isnan(b)
    return bool(np.all(nan | (a.view(np.uint64) == b.view(np.uint64))))


def rows_of(n: int, ncol: int = len(COLS), seed: int = 0) -> list[tuple]:
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n, ncol)) * 10.0 ** rng.integers(-9, 9, size=(n, ncol))
    a[:, 0] = np.arange(n) * 0.001
    a[:, 1] = np.arange(n) // 10
    a[:, 5] = (np.arange(n) // 7) % 8
    return [tuple(r) for r in a.tolist()]


def file_rows(path) -> int:
    with open(path, "rb") as f:
        return f.read().count(b"\n") - 1


# --- round trip -------------------------------------------------------------------------------------
def test_round_trip_exact_with_nan_inf_and_extremes(tmp_path):
    path = tmp_path / "trace.csv"
    rows = rows_of(300)
    rows += [(np.nan, -0.0, 0.0, 1e308, -1.7976931348623157e308, 5e-324, -2.2250738585072014e-308, np.inf,
              -np.inf),
             (1e-300, 1e300, 0.1, 1 / 3, 2.0 ** 53 + 2, -123456789.123456789, 1e-5, 9.999999999999999e22, 7.0)]
    rec = TraceRecorder(COLS, UNITS, csv_path=path, meta={"program": "dist_1.nc", "seed": 3})
    for r in rows:
        rec.append(r)
    assert rec.rows == len(rows)
    kept = rec.close()
    expected = np.array(rows, dtype=np.float64)
    assert same_bits(kept.data, expected)
    loaded = Trace.from_csv(path)
    assert loaded.columns == COLS
    assert same_bits(loaded.data, expected)
    assert loaded.units == UNITS
    assert loaded.meta == {"program": "dist_1.nc", "seed": 3}
    assert loaded == kept
    assert np.isnan(loaded["t"][-2]) and np.signbit(loaded["line"][-2])


def test_random_bit_patterns_round_trip(tmp_path):
    rng = np.random.default_rng(11)
    a = rng.integers(0, 2 ** 64, size=(20_000, 6), dtype=np.uint64).view(np.float64)
    rec = TraceRecorder([f"c{i}" for i in range(6)], csv_path=tmp_path / "bits.csv", chunk_rows=4096)
    for r in a.tolist():
        rec.append(tuple(r))
    kept = rec.close()
    assert same_bits(kept.data, a)
    assert same_bits(Trace.from_csv(tmp_path / "bits.csv").data, a)


def test_header_and_integer_columns_in_file(tmp_path):
    path = tmp_path / "t.csv"
    with TraceRecorder(COLS, UNITS, csv_path=path) as rec:
        rec.append((0.0, 12.0, 20.0, 20.0, 19.5, 1.0, -0.25, 18.0, 1.0))
        rec.append((0.001, 12.0, 20.0, 20.0, 19.5, 4.0, np.nan, 18.0, 1.0))
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(COLS)
    assert lines[1] == "0,12,20,20,19.5,1,-0.25,18,1"
    assert lines[2] == "0.001,12,20,20,19.5,4,nan,18,1"


def test_trace_to_csv_and_back(tmp_path):
    data = np.array(rows_of(100))
    tr = Trace(COLS, data, units=UNITS, meta={"k": [1, 2]})
    tr.to_csv(tmp_path / "x.csv")
    back = Trace.from_csv(tmp_path / "x.csv")
    assert back == tr
    assert back["Z.act"].shape == (100,)
    assert same_bits(back["Z.act"], data[:, 4])
    assert np.array_equal(back.t, data[:, 0])
    assert len(back) == back.rows == 100 and "Z.act" in back and "nope" not in back


def test_empty_and_single_row(tmp_path):
    rec = TraceRecorder(COLS, csv_path=tmp_path / "e.csv")
    tr = rec.close()
    assert tr.data.shape == (0, len(COLS))
    assert Trace.from_csv(tmp_path / "e.csv").data.shape == (0, len(COLS))
    rec = TraceRecorder(["a"], csv_path=tmp_path / "one.csv")
    rec.append((2.5,))
    rec.close()
    back = Trace.from_csv(tmp_path / "one.csv")
    assert back.data.shape == (1, 1) and back["a"][0] == 2.5


# --- chunking and streaming ---------------------------------------------------------------------------
def test_chunking_many_rows(tmp_path):
    path = tmp_path / "c.csv"
    rows = rows_of(10_007, seed=2)
    rec = TraceRecorder(COLS, csv_path=path, chunk_rows=64)
    for i, r in enumerate(rows):
        rec.append(r)
        assert rec.buffered_rows < 64
        if i % 1000 == 999:
            assert file_rows(path) == (i + 1) // 64 * 64   # whole chunks on disk as they fill
    kept = rec.close()
    assert rec.rows == len(rows)
    assert same_bits(kept.data, np.array(rows))
    assert same_bits(Trace.from_csv(path).data, np.array(rows))


def test_keep_false_holds_at_most_one_chunk(tmp_path):
    path = tmp_path / "s.csv"
    rows = rows_of(5_000, seed=3)
    rec = TraceRecorder(COLS, csv_path=path, keep=False, chunk_rows=100)
    for r in rows:
        rec.append(r)
        assert rec.buffered_rows <= 100 and rec.kept_rows == 0 and rec._chunks == []
    assert rec.rows == 5_000
    assert rec.close() is None
    assert same_bits(Trace.from_csv(path).data, np.array(rows))


def test_file_is_valid_after_every_flush(tmp_path):
    path = tmp_path / "live.csv"
    rows = rows_of(1_000, seed=4)
    rec = TraceRecorder(COLS, UNITS, csv_path=path, chunk_rows=10_000)
    for k in range(10):
        for r in rows[k * 100:(k + 1) * 100]:
            rec.append(r)
        rec.flush()
        mid = Trace.from_csv(path)          # read back mid-run
        assert same_bits(mid.data, np.array(rows[:(k + 1) * 100]))
        assert mid.units == UNITS
    rec.close()


def test_partial_last_line_is_ignored(tmp_path):
    path = tmp_path / "cut.csv"
    rec = TraceRecorder(["a", "b"], csv_path=path)
    rec.append((1.0, 2.0))
    rec.append((3.0, 4.0))
    rec.flush()
    with open(path, "ab") as f:          # a run killed in the middle of writing a row
        f.write(b"5.5,6")
    back = Trace.from_csv(path)
    assert back.data.tolist() == [[1.0, 2.0], [3.0, 4.0]]


def test_interrupted_write_is_cut_back(tmp_path):
    path = tmp_path / "int.csv"
    rec = TraceRecorder(["a", "b"], csv_path=path)
    rec.append((1.0, 2.0))
    rec.flush()
    rec._file.write(b"9,9\n7,")          # as if a write had been interrupted half way
    rec.append((3.0, 4.0))
    rec.close()
    assert Trace.from_csv(path).data.tolist() == [[1.0, 2.0], [3.0, 4.0]]


def test_append_raw_and_tick(tmp_path):
    rec = TraceRecorder(["a"], csv_path=tmp_path / "r.csv", chunk_rows=10, keep=False)
    for i in range(95):
        rec.append_raw((float(i),))
        if i % 5 == 4:
            rec.tick()
        assert rec.buffered_rows <= 10
    rec.close()
    assert Trace.from_csv(tmp_path / "r.csv")["a"].tolist() == [float(i) for i in range(95)]


# --- sidecar ------------------------------------------------------------------------------------------
def test_sidecar_at_open_and_close(tmp_path):
    path = tmp_path / "m.csv"
    meta = {"program": "dist_2.nc", "kp": np.float64(1.5), "cycle_s": 0.001, "path": tmp_path}
    rec = TraceRecorder(COLS, UNITS, csv_path=path, meta=meta)
    side = sidecar_path(path)
    assert side.name == "m.csv.meta.json"
    doc = json.loads(side.read_text())
    assert doc["units"] == UNITS and doc["meta"]["program"] == "dist_2.nc" and doc["meta"]["kp"] == 1.5
    assert doc["complete"] is False and doc["columns"] == COLS
    rec.append(rows_of(1)[0])
    rec.close()
    doc = json.loads(side.read_text())
    assert doc["complete"] is True and doc["rows"] == 1
    assert doc["meta"]["path"] == str(tmp_path)
    back = Trace.from_csv(path)
    assert back.units == UNITS and back.meta["cycle_s"] == 0.001


def test_from_csv_without_sidecar(tmp_path):
    path = tmp_path / "plain.csv"
    path.write_text("t,x\n0,1.5\n0.001,nan\n")
    tr = Trace.from_csv(path)
    assert tr.units == {} and tr.meta == {}
    assert tr["x"][0] == 1.5 and np.isnan(tr["x"][1])


def test_units_of_unknown_columns_are_dropped():
    rec = TraceRecorder(["t", "a"], units={"t": "s", "zzz": "mm"})
    assert rec.units == {"t": "s"}
    assert rec.close().units == {"t": "s"}


# --- close, errors ------------------------------------------------------------------------------------
def test_close_is_idempotent(tmp_path):
    path = tmp_path / "i.csv"
    rec = TraceRecorder(["a"], csv_path=path)
    rec.append((1.0,))
    first = rec.close()
    assert rec.closed
    assert rec.close() is first
    assert rec.close() is first
    assert Trace.from_csv(path)["a"].tolist() == [1.0]


def test_close_in_finally_after_exception(tmp_path):
    path = tmp_path / "f.csv"
    rec = TraceRecorder(["a"], csv_path=path, chunk_rows=7)
    with pytest.raises(KeyboardInterrupt):
        try:
            for i in range(50):
                rec.append((float(i),))
                if i == 30:
                    raise KeyboardInterrupt
        finally:
            rec.close()
    assert Trace.from_csv(path)["a"].tolist() == [float(i) for i in range(31)]


def test_rows_after_close_are_reported():
    rec = TraceRecorder(["a"], chunk_rows=2)
    app = rec.append
    rec.close()
    app((1.0,))
    with pytest.raises(RuntimeError):
        app((2.0,))


def test_malformed_row_raises_and_is_dropped(tmp_path):
    rec = TraceRecorder(["a", "b"], csv_path=tmp_path / "bad.csv", chunk_rows=4)
    rec.append((1.0, 2.0))
    rec.append((3.0,))
    rec.append((5.0, 6.0))
    with pytest.raises(ValueError, match="row 1"):
        rec.append((7.0, 8.0))
    rec.append(("9.5", 1.0))               # a string is not a number, even if numpy would parse it
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tr = rec.close()
    assert any("row 3" in str(w.message) for w in caught)
    assert tr.data.tolist() == [[1.0, 2.0], [5.0, 6.0], [7.0, 8.0]]
    assert Trace.from_csv(tmp_path / "bad.csv").data.tolist() == tr.data.tolist()


def test_bad_columns_are_rejected():
    for cols in ([], ["a", "a"], ["a,b"], [" a"], [""]):
        with pytest.raises(ValueError):
            TraceRecorder(cols)
    with pytest.raises(ValueError):
        TraceRecorder(["a"], chunk_rows=0)
    with pytest.raises(ValueError):
        Trace(["a", "b"], np.zeros((3, 3)))


def test_unknown_column_key_error():
    tr = Trace(["Z.act"], np.zeros((2, 1)))
    with pytest.raises(KeyError, match="Z.act"):
        tr["Z.akt"]


def test_numpy_rows_and_ints_accepted():
    rec = TraceRecorder(["a", "b", "c"], chunk_rows=3)
    rec.append(np.array([1.0, 2.0, 3.0]))
    rec.append((np.float64(4.0), 5, True))
    rec.append([7.0, 8.0, 9.0])
    assert rec.close().data.tolist() == [[1, 2, 3], [4, 5, 1], [7, 8, 9]]


# --- a million rows (its speed target, < 3 s, is measured by bench/bench_run.py) ---------------------
def test_append_million_rows_of_25_floats_keeps_every_row():
    cols = [f"s{i}" for i in range(25)]
    rec = TraceRecorder(cols)
    append = rec.append
    for k in range(1_000_000):
        append((float(k),) + (0.5,) * 23 + (-float(k),))
    tr = rec.close()
    assert tr.data.shape == (1_000_000, 25)
    assert np.array_equal(tr.data[:, 0], np.arange(1_000_000.0)) and np.array_equal(tr.data[:, 24], -tr.data[:, 0])
    assert np.all(tr.data[:, 1:24] == 0.5)


def test_packed_rows_equal_tuple_rows_and_a_bad_packed_row_is_dropped(tmp_path):
    cols = ["t", "a", "b"]
    rows = [(k * 0.001, float(k), -k / 3.0) for k in range(2500)]
    plain = TraceRecorder(cols, csv_path=tmp_path / "plain.csv", chunk_rows=700)
    packed = TraceRecorder(cols, csv_path=tmp_path / "packed.csv", chunk_rows=700, packed=True)
    for r in rows:
        plain.append(r)
        packed.append(packed.pack(*r))
    a, b = plain.close(), packed.close()
    assert np.array_equal(a.data, b.data) and b.data.shape == (2500, 3)
    assert (tmp_path / "plain.csv").read_bytes() == (tmp_path / "packed.csv").read_bytes()
    # a row of the wrong length: raised at its flush, dropped, the others kept
    rec = TraceRecorder(cols, chunk_rows=10, packed=True)
    for k in range(5):
        rec.append(rec.pack(k, k, k))
    rec.append(b"\0" * 16)
    with pytest.raises(ValueError, match="trace row 5 is not 3 numbers"):
        rec.flush()
    rec.append(rec.pack(9.0, 9.0, 9.0))
    tr = rec.close()
    assert tr.data.shape == (6, 3) and tr.data[-1, 0] == 9.0
