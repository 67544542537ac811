"""A sweep that fits in one chunk runs in this process: the embedded cluster could not spread one chunk
over its workers and would only add its start-up (issue 13: the second sweep call within 2 s)."""
from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from distctrl.cli import main

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def test_a_one_chunk_sweep_runs_in_this_process_and_says_so(tmp_path):
    res = CliRunner().invoke(main, ["sweep", str(SCN / "tune_sheet.toml"), "--random", "4", "--cycles", "300",
                                    "--out", str(tmp_path / "s.csv"), "--json"])
    assert res.exit_code == 0, res.output
    js = json.loads(res.stdout)
    assert js["mode"] == "local" and js["sets"] == 4
    assert "fit in one chunk: running in this process" in res.stderr
