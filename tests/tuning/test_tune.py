"""tune() on a small budget improves the scenario's RMS error; its outputs load again; the CLI."""
from __future__ import annotations

from pathlib import Path

import click
import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.nc import parse_program  # noqa: E402
from distctrl.params import parse_list_text  # noqa: E402
from distctrl.cli.tune import sweep, tune_cmd  # noqa: E402
from distctrl.tuning.tune import nc_block, plot_before_after, tune  # noqa: E402

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml"


@pytest.fixture(scope="module")
def result():
    return tune(SCN, budget=60, seed=1, cycles=2000, mode="local", progress=False)


def test_tune_improves_and_outputs_load(result):
    assert result.best_metrics["rms_error"] < 0.97 * result.base_metrics["rms_error"]   # the base (kp 0.5, MA 4) is fair
    assert result.evaluations <= 60
    loaded = parse_list_text(result.param_list).params
    for f in ("kp", "i_tn", "d_tv", "filter_type", "n_cycles", "smoothing_factor", "kalman_sigma",
              "low_pass_filter_order", "low_pass_filter_fg_f0"):
        a, b = getattr(loaded, f), getattr(result.best, f)
        assert a == pytest.approx(b, rel=1e-9) if isinstance(b, float) else a == b, f
    block = result.nc_block
    assert block.startswith("Z[DIST_CTRL KP=")
    parse_program(f"%T\nN10 {block}\nN20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\nN30 M30\n")
    names = [r["name"] for r in result.robustness]
    assert names == ["noise x2", "surface x1.5", "kv x0.7"]
    assert all(not r["failed"] for r in result.robustness)
    text = result.report()
    assert "margin" in text and "kenngr.distc.kp" in text


def test_nc_block_words():
    from distctrl.control import FilterType
    from distctrl.params import AxisParameters
    p = AxisParameters(enabled=True, kp=0.4, i_tn=0.1, d_tv=0.002, filter_type=FilterType.KALMAN_EXPO,
                       n_cycles=8, smoothing_factor=0.3, kalman_sigma=20.0)
    assert nc_block(p) == ("Z[DIST_CTRL KP=0.4 I_TN=0.1 D_TV=0.002 FILTER_TYPE=KALMAN_EXPO N_CYCLES=8 "
                           "SMOOTH_FACT=0.3 KALMAN_SIGMA=20]")
    parse_program(f"N10 {nc_block(p)}\nN20 M30\n")


def test_plot_before_after(result, tmp_path):
    plot_before_after(SCN, result.base, result.best, tmp_path / "ba.png", cycles=2000)
    assert (tmp_path / "ba.png").stat().st_size > 1000


@click.group()
def _cli():
    pass


_cli.add_command(sweep)
_cli.add_command(tune_cmd)


def test_cli_sweep_and_tune(tmp_path):
    r = CliRunner().invoke(_cli, ["sweep", str(SCN), "--grid", "kp=0.2,0.8,n_cycles=2,8", "--local", "--cycles",
                                  "1500", "--out", str(tmp_path / "s.csv"), "--plot", str(tmp_path / "s.png")])
    assert r.exit_code == 0, r.output
    assert "4 sets x 1500 cycles" in r.output and (tmp_path / "s.csv").exists() and (tmp_path / "s.png").exists()
    r = CliRunner().invoke(_cli, ["sweep", str(SCN), "--grid", "kp=0:1:3", "--local"])
    assert r.exit_code == 1 and "P-AXIS-00759" in r.output
    r = CliRunner().invoke(_cli, ["tune", str(SCN), "--budget", "20", "--local", "--cycles", "1500",
                                  "--no-robustness", "--out", str(tmp_path / "t")])
    assert r.exit_code == 0, r.output
    assert "Z[DIST_CTRL KP=" in r.output
    for f in ("tuned.lis", "tuned.nc.txt", "sweep.csv", "before_after.png", "report.txt"):
        assert (tmp_path / "t" / f).exists(), f


def test_a_tune_result_plots_itself_and_writes_its_sweep_as_csv(result, tmp_path):
    """The result face of python-control's results: plot() is the before/after figure of the run it
    was tuned on (plot_before_after on the same inputs), to_csv() the table of every evaluated set."""
    fig = result.plot(tmp_path / "ba.png")
    plot_before_after(SCN, result.base, result.best, tmp_path / "ref.png", cycles=2000)
    assert (tmp_path / "ba.png").read_bytes() == (tmp_path / "ref.png").read_bytes()
    assert type(fig.canvas).__name__ == "FigureCanvasAgg"
    error, offset = fig.axes
    assert len(error.get_lines()) == 3 and len(offset.get_lines()) == 2     # two runs (+ the zero line)
    assert [ln.get_label() for ln in offset.get_lines()] == ["scenario parameters", "tuned"]
    result.to_csv(tmp_path / "sweep.csv")
    result.sweep.to_csv(tmp_path / "ref.csv")
    assert (tmp_path / "sweep.csv").read_text() == (tmp_path / "ref.csv").read_text()
