"""The table ``distctrl sweep`` writes is the same bit for bit (issue 27): the fixtures were written by
the code before the sweep's packing and metrics were rebuilt (main at f07f8e1), with the commands below.
The CSV holds every float as its repr, so equal text is equal bits (offsets' metrics and errors)."""
from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from distctrl.cli import main

ROOT = Path(__file__).resolve().parents[2]
SCN = ROOT / "examples" / "scenarios"
DATA = Path(__file__).resolve().parent / "data"

CASES = {
    # 300 random sets of every filter kind (LOWPASS, MOVING_AVERAGE, KALMAN, EXP...), 7 of them fail
    "sweep_golden_random.csv": ["--random", "300", "--seed", "3"],
    # a grid whose fg_f0 = 800 Hz sets are rejected (above Nyquist), the rest LOWPASS of orders 1, 2, 4
    "sweep_golden_grid.csv": ["--grid", "kp=0.3,0.8,1.2,filter_type=LOWPASS,order=1,2,4,fg_f0=100,490,800"],
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_sweep_table_is_bit_for_bit_the_golden_one(tmp_path, name):
    out = tmp_path / name
    res = CliRunner().invoke(main, ["sweep", str(SCN / "tune_sheet.toml"), *CASES[name], "--local",
                                    "--out", str(out)])
    assert res.exit_code == 0, res.output
    got = out.read_text().splitlines()
    want = (DATA / name).read_text().splitlines()
    assert got[0] == want[0]
    assert len(got) == len(want)
    diff = [(i, a, b) for i, (a, b) in enumerate(zip(got, want)) if a != b]
    assert not diff, f"{len(diff)} rows differ, first: row {diff[0][0]}\n got  {diff[0][1]}\n want {diff[0][2]}"


def test_rejected_grid_sets_are_reported_as_before(tmp_path):
    res = CliRunner().invoke(main, ["sweep", str(SCN / "tune_sheet.toml"), *CASES["sweep_golden_grid.csv"],
                                    "--local", "--out", str(tmp_path / "g.csv")])
    assert res.exit_code == 0, res.output
    assert ("warning: 9 of 27 combinations rejected; first: parameter set kp=0.3 filter_type=LOWPASS "
            "low_pass_filter_order=1 low_pass_filter_fg_f0=800 is not valid: P-AXIS-00508 low_pass_filter_fg_f0 = "
            "800.0 Hz out of range for cycle time 0.001 s; allowed: 0 < fg_f0 < 500 Hz (Nyquist)") in res.stderr


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_sweep_packs_its_sets_as_columns_without_a_parameter_object_per_set(tmp_path, name, monkeypatch):
    """Issue 27: the CLI's sets go through the columns (check_columns, pack_columns), not build_sets /
    pack_sets, and give the golden table."""
    import distctrl.batch.closed_loop as CL
    import distctrl.cli.tune as cli_tune

    def refuse(*a, **k):
        raise AssertionError("a per-set path was taken")
    monkeypatch.setattr(cli_tune, "build_sets", refuse)
    monkeypatch.setattr(CL, "pack_sets", refuse)
    out = tmp_path / name
    res = CliRunner().invoke(main, ["sweep", str(SCN / "tune_sheet.toml"), *CASES[name], "--local",
                                    "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert out.read_text() == (DATA / name).read_text()
