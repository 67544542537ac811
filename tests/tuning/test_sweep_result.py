"""SweepResult has the result face of python-control's results: ``plot()`` (the sweep plot, Agg canvas),
``to_dict()`` (what ``distctrl sweep --json`` prints of it) and ``to_csv()``."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from click.testing import CliRunner

from distctrl.cli.common import json_text
from distctrl.tuning.runner import Evaluator, SweepResult, plot_sweep

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml"


def _grid_result() -> SweepResult:
    kp, n = np.meshgrid([0.2, 0.5, 0.8], [2, 4, 8, 16])
    rms = 0.05 + (kp.ravel() - 0.5) ** 2 + 0.001 * n.ravel()
    return SweepResult({"kp": kp.ravel(), "n_cycles": n.ravel(), "rms_error": rms, "cost": rms},
                       info={"sets": 12, "cycles": 1000, "seconds": 0.5, "mode": "local", "workers": 1})


def test_a_sweep_result_plots_itself_as_the_heatmap_or_parallel_coordinates(tmp_path):
    res = _grid_result()
    fig = res.plot(tmp_path / "heat.png")
    assert (tmp_path / "heat.png").read_bytes()[:4] == b"\x89PNG"
    assert type(fig.canvas).__name__ == "FigureCanvasAgg"
    ax = fig.axes[0]
    assert len(fig.axes) == 2 and len(ax.get_images()) == 1              # the heatmap and its colour bar
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("n_cycles", "kp")
    assert ax.get_images()[0].get_array().shape == (3, 4)
    irregular = SweepResult({"kp": np.linspace(0.1, 1.9, 7), "d_tv": np.linspace(0, 0.01, 7) ** 2,
                             "rms_error": np.linspace(1, 2, 7)})
    par = irregular.plot(metric="rms_error")
    assert len(par.axes[0].get_lines()) == 7 and not par.axes[0].get_images()
    # the module function stays as the method's alias
    assert len(plot_sweep(res).axes[0].get_images()) == 1


def test_a_sweep_result_to_dict_holds_the_best_rows_units_and_throughput():
    res = _grid_result()
    d = res.to_dict(top=3, key="rms_error")
    assert d["metric"] == "rms_error" and d["best"] == res.best_rows(3, key="rms_error")
    assert d["best"][0]["kp"] == 0.5 and d["best"][0]["n_cycles"] == 2
    assert (d["sets"], d["cycles"], d["seconds"], d["mode"], d["workers"]) == (12, 1000, 0.5, "local", 1)
    assert d["set_cycles_per_s"] == pytest.approx(12 * 1000 / 0.5)
    assert d["units"] == res.units() and d["notes"] == res.notes(3, key="rms_error")
    json.loads(json_text(d))                                            # JSON-ready


def test_sweep_json_prints_the_results_to_dict(tmp_path, monkeypatch):
    pytest.importorskip("numba")
    from distctrl.cli.tune import sweep

    seen = []
    for name in ("evaluate", "evaluate_points"):       # the sweep's sets as columns: evaluate_points
        def keep(self, *a, _f=getattr(Evaluator, name), **k):
            seen.append(_f(self, *a, **k))
            return seen[-1]
        monkeypatch.setattr(Evaluator, name, keep)
    r = CliRunner().invoke(sweep, [str(SCN), "--grid", "kp=0.2,0.8,n_cycles=2,8", "--local", "--cycles", "1000",
                                   "--out", str(tmp_path / "s.csv"), "--top", "3", "--metric", "cost", "--json"])
    assert r.exit_code == 0, r.output
    printed = json.loads(r.stdout)
    (res,) = seen
    d = json.loads(json_text(res.to_dict(top=3, key="cost")))
    assert {k: printed[k] for k in d} == d
    res.to_csv(tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_text() == (tmp_path / "s.csv").read_text()


def test_rows_made_beforehand_are_written_only_while_the_table_is_the_one_they_were_made_from(tmp_path):
    """evaluate_points hands the table the CSV rows its chunks made (csv_rows); written while the table's
    names and values are those they were made from, else the table is formatted as it is."""
    from distctrl.tuning.runner import SweepResult, csv_rows

    data = {"a": np.array([0.5, np.nan, -0.0]), "b": np.array([1, 2, 3]), "c": ["x", "y,z", 'q"']}
    assert csv_rows(data) == '0.5,1,x\r\n,2,"y,z"\r\n-0.0,3,"q"""\r\n'
    res = SweepResult({k: (v.copy() if isinstance(v, np.ndarray) else list(v)) for k, v in data.items()},
                      csv_body="made,beforehand,1\r\n")
    res.write(tmp_path / "one.csv")
    assert (tmp_path / "one.csv").read_text().splitlines() == ["a,b,c", "made,beforehand,1"]
    res.data["b"][1] = 7                                            # changed in place: formatted now
    res.write(tmp_path / "two.csv")
    assert (tmp_path / "two.csv").read_text().splitlines() == ["a,b,c", "0.5,1,x", ',7,"y,z"', '-0.0,3,"q"""']
    plain = SweepResult(dict(data))
    plain.write(tmp_path / "three.csv")
    assert (tmp_path / "three.csv").read_text().splitlines()[1:] == ["0.5,1,x", ',2,"y,z"', '-0.0,3,"q"""']


def test_a_table_changed_in_place_after_the_sweep_is_written_as_it_is_now(tmp_path):
    """The CSV text a local sweep's chunks made beforehand is written only while the table is unchanged:
    a value changed in place afterwards is in the file."""
    from distctrl.batch.closed_loop import prepare
    from distctrl.tuning.columns import drop_inert_columns, random_columns

    inputs = prepare(SCN, cycles=300)
    pc, _ = drop_inert_columns(random_columns(40, 2, cycle_time=inputs.cycle_time))
    with Evaluator(inputs, mode="local", chunk_size=8, progress=False) as ev:
        res = ev.evaluate_points(inputs.params, pc)
    res.write(tmp_path / "before.csv")
    res.data["rms_error"][3] = 123.25
    res.data["kp"][5] = 0.625
    res.data["filter_type"][0] = "PASS"
    res.write(tmp_path / "after.csv")
    before = (tmp_path / "before.csv").read_text().splitlines()
    after = (tmp_path / "after.csv").read_text().splitlines()
    cols = before[0].split(",")
    assert after[4].split(",")[cols.index("rms_error")] == "123.25"
    assert after[6].split(",")[cols.index("kp")] == "0.625"
    assert after[1].split(",")[cols.index("filter_type")] == "PASS"
    assert [a for a, b in zip(after, before) if a != b] == [after[1], after[4], after[6]]


def _csv_module_rows(data: dict) -> str:
    """The definition csv_rows keeps: the csv module on the table's Python values (numpy scalars as Python
    numbers, a NaN as an empty field)."""
    import csv
    import io

    def value(x):
        x = x.item() if isinstance(x, np.generic) else x
        return "" if isinstance(x, float) and x != x else x
    buf = io.StringIO()
    csv.writer(buf).writerows(zip(*[[value(x) for x in v] for v in data.values()]))
    return buf.getvalue()


_floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
_column = st.one_of(
    st.lists(_floats, min_size=3, max_size=3).map(np.array),
    st.lists(st.integers(-2**62, 2**62), min_size=3, max_size=3).map(np.array),
    st.lists(st.booleans(), min_size=3, max_size=3).map(lambda v: np.array(v, dtype=bool)),
    st.lists(st.one_of(st.text(max_size=6), st.sampled_from(["KALMAN_MA", "PT1", "a,b", 'q"', "x\r\ny", ""]),
                       st.none(), _floats, st.integers()), min_size=3, max_size=3))


@settings(max_examples=300, deadline=None)
@given(st.lists(_column, min_size=1, max_size=5))
def test_csv_rows_are_the_csv_module_s_rows_of_any_table(columns):
    """csv_rows joins the fields itself where no field needs quoting (a third faster than the csv module over a
    sweep's 10 000 rows): the same text as the csv module for any table of floats (NaN, infinities, -0.0),
    integers, booleans and text (commas, quotes, line breaks, None, empty)."""
    from distctrl.tuning.runner import csv_rows

    data = {f"c{i}": c for i, c in enumerate(columns)}
    assert csv_rows(data) == _csv_module_rows(data)
