"""SweepResult has the result face of python-control's results: ``plot()`` (the sweep plot, Agg canvas),
``to_dict()`` (what ``distctrl sweep --json`` prints of it) and ``to_csv()``."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
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


def test_float_fields_are_what_the_csv_module_writes_for_the_floats():
    import csv
    import io

    from distctrl.tuning.runner import _csv_column, float_fields

    v = np.array([0.1, -0.0, 0.0, np.nan, np.inf, -np.inf, 1e-5, 1e16, 123456.789, 5e-324, -1.5])
    plain = io.StringIO()
    csv.writer(plain).writerows([[x] for x in _csv_column(v)])
    made = io.StringIO()
    csv.writer(made).writerows([[x] for x in float_fields(v)])
    assert made.getvalue() == plain.getvalue()


def test_fields_made_beforehand_are_written_only_for_the_column_they_were_made_for(tmp_path):
    """evaluate_points hands the table the CSV fields its chunks made; a column replaced afterwards is
    formatted from its values."""
    from distctrl.tuning.runner import SweepResult, float_fields

    col = np.array([0.5, np.nan, 2.0])
    res = SweepResult({"a": col, "b": np.array([1.0, 2.0, 3.0])}, fields={"a": (col, float_fields(col))})
    res.write(tmp_path / "one.csv")
    assert (tmp_path / "one.csv").read_text().splitlines() == ["a,b", "0.5,1.0", ",2.0", "2.0,3.0"]
    res.data["a"] = np.array([7.0, 8.0, 9.0])                      # replaced: the old fields are not used
    res.write(tmp_path / "two.csv")
    assert (tmp_path / "two.csv").read_text().splitlines() == ["a,b", "7.0,1.0", "8.0,2.0", "9.0,3.0"]
    stale = SweepResult({"a": col}, fields={"a": (np.array([1.0, 2.0, 3.0]), ["1.0", "2.0", "3.0"])})
    stale.write(tmp_path / "three.csv")                            # fields of another array: not taken
    assert (tmp_path / "three.csv").read_text().splitlines() == ["a", "0.5", '""', "2.0"]   # (csv quotes a lone empty field)


def test_csv_fields_of_integers_and_booleans_are_what_the_csv_module_writes():
    import csv
    import io

    from distctrl.tuning.runner import _csv_column, csv_fields

    for v in (np.array([0, -3, 2**40]), np.array([True, False]), np.array([1, 7], dtype=np.uint8),
              np.array([0.25, np.nan])):
        plain, made = io.StringIO(), io.StringIO()
        csv.writer(plain).writerow(_csv_column(v))
        csv.writer(made).writerow(csv_fields(v))
        assert made.getvalue() == plain.getvalue()
    with pytest.raises(TypeError):
        csv_fields(np.array(["a"], dtype=object))
