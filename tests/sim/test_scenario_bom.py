"""A scenario, its NC program and the lists it names, saved with a UTF-8 byte-order mark (Windows
editors), load like the same files without it (new-user audit R3: a scenario with a BOM was refused
with "toml: syntax error: 'Invalid statement (at line 1, column 1)'")."""
from __future__ import annotations

import shutil
from pathlib import Path

from click.testing import CliRunner

from distctrl.cli import main
from distctrl.sim.scenario import load_scenario

EX = Path(__file__).resolve().parents[2] / "examples"
BOM = b"\xef\xbb\xbf"


def _examples(tmp_path: Path, bom: bool, crlf: bool = False) -> Path:
    """The examples folder copied into tmp_path; every scenario, NC program and list in it with a BOM
    (and CRLF line ends) when asked."""
    dst = tmp_path / "examples"
    shutil.copytree(EX, dst)
    for p in dst.rglob("*"):
        if p.suffix in (".toml", ".nc", ".lis"):
            data = p.read_bytes()
            p.write_bytes((BOM if bom else b"") + (data.replace(b"\n", b"\r\n") if crlf else data))
    return dst / "scenarios"


def test_a_scenario_its_program_and_list_with_a_bom_load_like_without(tmp_path):
    for d in "abc":
        (tmp_path / d).mkdir()
    plain = load_scenario(_examples(tmp_path / "a", bom=False) / "dist_1.toml")
    for sc in (load_scenario(_examples(tmp_path / "b", bom=True) / "dist_1.toml"),
               load_scenario(_examples(tmp_path / "c", bom=True, crlf=True) / "dist_1.toml")):
        assert sc.program_text.replace("\r\n", "\n") == plain.program_text
        assert {k: a.params for k, a in sc.axes.items()} == {k: a.params for k, a in plain.axes.items()}
        assert sc.duration == plain.duration


def test_a_3d_scenario_and_its_external_variable_list_with_a_bom_load_like_without(tmp_path):
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    plain = load_scenario(_examples(tmp_path / "a", bom=False) / "dist3d_1.toml")
    with_bom = load_scenario(_examples(tmp_path / "b", bom=True) / "dist3d_1.toml")
    assert with_bom.external_variables == plain.external_variables


def test_run_of_a_scenario_with_a_bom_exits_0(tmp_path):
    r = CliRunner().invoke(main, ["run", str(_examples(tmp_path, bom=True) / "dist_1.toml"), "--json"])
    assert r.exit_code == 0, r.output
