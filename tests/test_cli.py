"""The command line: exit codes and messages at the edge."""
from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from distctrl.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_params_prints_the_list_back_and_exits_0():
    res = CliRunner().invoke(main, ["params", str(ROOT / "examples" / "axis_z_9_3.lis")])
    assert res.exit_code == 0
    assert "kenngr.distc.kalman_sigma" in res.output and "1000" in res.output


def test_params_bad_file_exits_1_naming_line_and_range(tmp_path):
    f = tmp_path / "bad.lis"
    f.write_text("kenngr.distc.n_cycles 20\nkenngr.distc.kp 3\n")
    res = CliRunner().invoke(main, ["params", str(f)])
    assert res.exit_code == 1
    assert f"{f}:2:" in res.output and "P-AXIS-00759" in res.output and "0 < value <= 2" in res.output


def test_demo_runs_without_errors_and_tracks_the_sheet():
    from distctrl.demo import main as demo
    results = demo()
    assert len(results) == 3
    for r in results:
        assert r.errors == []
        assert r.distance_error_rms < 0.3              # dominated by the 2.8 mm obstacle edges
    assert results[1].max_offset < results[0].max_offset   # both encoders: no overshoot
