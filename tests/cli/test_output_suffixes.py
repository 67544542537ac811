"""Output files are checked by their suffix before anything runs, in every command, with one line and the
--json error object (new-user audit B3: ``run --plot x.bmp`` and ``sweep --plot x.bmp`` ran to the end and
died with a traceback, stdout empty with --json; R4: ``sweep --out s.xlsx`` wrote CSV into s.xlsx)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from distctrl.cli import main

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
DIST_1 = str(SCN / "dist_1.toml")
SHEET = str(SCN / "tune_sheet.toml")

CASES = [
    # (argv with {d} for the folder, the file named in the message, the allowed suffixes in the message)
    (["run", DIST_1, "--trace", "{d}/t.csv", "--plot", "{d}/x.bmp"], "x.bmp", ".png, .svg, .pdf"),
    (["run", DIST_1, "--trace", "{d}/t.csv", "--plot", "{d}/r.txt"], "r.txt", ".png, .svg, .pdf"),
    (["run", DIST_1, "--trace", "{d}/t.xlsx"], "t.xlsx", ".csv, .parquet"),
    (["sweep", SHEET, "--random", "4", "--local", "--out", "{d}/s.csv", "--plot", "{d}/sw.bmp"], "sw.bmp",
     ".png, .svg, .pdf"),
    (["sweep", SHEET, "--random", "4", "--local", "--out", "{d}/s.xlsx"], "s.xlsx", ".csv, .parquet"),
    (["filters", "--plot", "{d}/f.bmp"], "f.bmp", ".png, .svg, .pdf"),
    (["plot", "{d}/none.csv", "-o", "{d}/p.bmp"], "p.bmp", ".png, .svg, .pdf, .jpg, .jpeg"),
    # machine record writes CSV only: a .parquet name got CSV content (nothing listens on port 1)
    (["machine", "record", "--ads", "127.0.0.1.1.1", "--ip", "127.0.0.1", "--port", "1", "--axis", "Z=3",
      "--seconds", "1", "--out", "{d}/rec.parquet"], "rec.parquet", ".csv"),
]


@pytest.mark.parametrize("argv, name, allowed", CASES, ids=[" ".join(c[0][:1] + c[0][-2:]) for c in CASES])
@pytest.mark.parametrize("as_json", [False, True])
def test_an_unsupported_suffix_is_refused_in_one_line_before_anything_runs(tmp_path, argv, name, allowed,
                                                                           as_json):
    args = [a.replace("{d}", str(tmp_path)) for a in argv] + (["--json"] if as_json else [])
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 1, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    suffix = Path(name).suffix
    assert lines[0].startswith("error: ") and f"{name}" in lines[0], lines[0]
    assert f"suffix '{suffix}' not supported; allowed: {allowed}" in lines[0], lines[0]
    assert "Traceback" not in r.output
    if as_json:
        d = json.loads(r.stdout)
        assert d["outcome"] == "error" and d["exit_code"] == 1 and d["error"] == lines[0][len("error: "):]
    else:
        assert r.stdout == ""
    # before anything ran: no file of the command was written
    assert sorted(p.name for p in tmp_path.iterdir()) == [], list(tmp_path.iterdir())
