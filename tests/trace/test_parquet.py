"""Traces as Parquet (distctrl.trace.parquet): exact round trip with units and meta in the schema
metadata; a clear error when pyarrow is missing."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from distctrl.errors import DistCtrlError
from distctrl.trace import Trace
from distctrl.trace.parquet import METADATA_KEY, ParquetError, from_parquet, to_parquet

ROOT = Path(__file__).resolve().parents[2]


def test_without_pyarrow_the_error_says_how_to_install(monkeypatch, tmp_path):
    # a None entry in sys.modules makes the import fail as if the package were not installed
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    trace = Trace(["t", "x"], [[0.0, 1.0]])
    for call in (lambda: to_parquet(trace, tmp_path / "a.parquet"),
                 lambda: from_parquet(tmp_path / "a.parquet")):
        with pytest.raises(DistCtrlError, match=r"pip install 'distctrl\[parquet\]'"):
            call()


def _pyarrow():
    try:
        import pyarrow
    except ImportError as exc:
        pytest.skip(f"pyarrow is not installed ({exc}); it is optional (pip install pyarrow): "
                    "the Parquet round trip is not tested")
    return pyarrow


def test_run_trace_round_trip(tmp_path):
    _pyarrow()
    from distctrl.sim.runner import run

    trace = run(ROOT / "examples" / "scenarios" / "dist_1.toml").trace
    path = to_parquet(trace, tmp_path / "sub" / "dist_1.parquet")
    assert path.is_file() and path.read_bytes()[:4] == b"PAR1"
    back = from_parquet(path)
    assert back == trace                  # columns, units, meta, data bit for bit
    assert back.unit("Z.act") == "mm" and back.meta["scenario"].startswith("dist_1")


def test_special_values_and_meta(tmp_path):
    _pyarrow()
    data = np.array([[0.0, -0.0, np.nan, 1e-310], [np.inf, -np.inf, 1.0 / 3.0, -1e300], [2.0, 3.0, 4.0, 5.0]])
    trace = Trace(["t", "a.b", "c", "d"], data, units={"t": "s", "a.b": "mm"},
                  meta={"program": "x.nc", "nested": {"k": [1, 2.5, None]}, "tuple": (1, 2)})
    for codec in ("zstd", "snappy", "none"):
        back = from_parquet(to_parquet(trace, tmp_path / f"{codec}.parquet", compression=codec))
        assert back.columns == trace.columns and back.units == trace.units
        assert back.meta == {"program": "x.nc", "nested": {"k": [1, 2.5, None]}, "tuple": [1, 2]}
        real = ~np.isnan(data)
        assert np.array_equal(back.data.view(np.uint64)[real], data.view(np.uint64)[real])
        assert np.array_equal(np.isnan(back.data), np.isnan(data))


def test_schema_metadata_and_field_units(tmp_path):
    _pyarrow()
    import pyarrow.parquet as pq

    trace = Trace(["t", "Z.act"], [[0.0, 1.0], [0.001, 1.5]], units={"t": "s", "Z.act": "mm"}, meta={"k": 1})
    path = to_parquet(trace, tmp_path / "a.parquet")
    schema = pq.read_schema(path)
    doc = json.loads(schema.metadata[METADATA_KEY])
    assert doc["format"] == "distctrl-trace" and doc["meta"] == {"k": 1}
    assert doc["units"] == {"t": "s", "Z.act": "mm"}
    assert schema.field("Z.act").metadata[b"unit"] == b"mm"
    assert str(schema.field("t").type) == "double"


def test_empty_trace(tmp_path):
    _pyarrow()
    trace = Trace(["t", "y"], np.empty((0, 2)), units={"t": "s"})
    assert from_parquet(to_parquet(trace, tmp_path / "e.parquet")) == trace


def test_foreign_parquet_file(tmp_path):
    pa = _pyarrow()
    import pyarrow.parquet as pq

    table = pa.table({"t": pa.array([0.0, 1.0]), "n": pa.array([1, None], type=pa.int32()),
                      "flag": pa.array([True, False])})
    table = table.replace_schema_metadata(None)
    pq.write_table(table.cast(pa.schema([pa.field("t", pa.float64(), metadata={"unit": "s"}),
                                         pa.field("n", pa.int32()), pa.field("flag", pa.bool_())])),
                   tmp_path / "f.parquet")
    back = from_parquet(tmp_path / "f.parquet")
    assert back.columns == ["t", "n", "flag"] and back.units == {"t": "s"} and back.meta == {}
    assert back.data[0].tolist() == [0.0, 1.0, 1.0] and np.isnan(back.data[1, 1])

    pq.write_table(pa.table({"s": pa.array(["a"])}), tmp_path / "s.parquet")
    with pytest.raises(ParquetError, match="not numeric"):
        from_parquet(tmp_path / "s.parquet")
    with pytest.raises(ParquetError, match="no such Parquet file"):
        from_parquet(tmp_path / "missing.parquet")
    (tmp_path / "bad.parquet").write_text("not parquet")
    with pytest.raises(ParquetError, match="cannot read as Parquet"):
        from_parquet(tmp_path / "bad.parquet")
