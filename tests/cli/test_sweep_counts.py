"""``sweep --random N`` says what became of each of the N sets (new-user audit R4: ``--random 10000``
evaluated 9992 sets and the 8 merged duplicates were named only as "grid combinations" on stderr, not in
the summary line nor in --json)."""
from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from distctrl.cli import main

SHEET = str(Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml")


def _sweep(tmp_path, *extra):
    return CliRunner().invoke(main, ["sweep", SHEET, "--random", "10000", "--local", "--cycles", "200",
                                     "--out", str(tmp_path / "s.csv"), *extra])


def test_json_accounts_for_every_requested_set(tmp_path):
    r = _sweep(tmp_path, "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["requested"] == 10000
    assert d["merged"] > 0                                  # this sample has sets equal but for d_tv
    assert d["sets"] + d["merged"] + d["rejected"] == 10000, d


def test_the_summary_line_says_why_sets_were_dropped(tmp_path):
    r = _sweep(tmp_path)
    assert r.exit_code == 0, r.output
    last = r.stdout.strip().splitlines()[-1]
    d = json.loads(_sweep(tmp_path, "--json").stdout)
    assert f"{d['sets']} of 10000 sets" in last and f"{d['merged']} merged" in last, last
    assert "grid combinations" not in r.stderr, r.stderr          # a random sample is not a grid
