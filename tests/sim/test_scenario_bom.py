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


def test_a_linearisation_table_with_a_bom_loads_like_without(tmp_path):
    """The table `distctrl calibrate` writes, edited on Windows: [sensor] linearisation = "FILE"."""
    table = b"linearisation = [[0.0, 0.0], [0.56, 0.5], [1.08, 1.0], [2.1, 2.0], [5.0, 5.1], [9.5, 10.0]]\n"
    loaded = []
    for d, bom in (("a", b""), ("b", BOM)):
        (tmp_path / d).mkdir()
        scn = _examples(tmp_path / d, bom=False)
        (scn / "lin.toml").write_bytes(bom + table)
        toml = scn / "calibrate_capacitive.toml"
        commented = '# linearisation = "calibrate_capacitive_linearisation.toml"'
        toml.write_text(toml.read_text().replace(commented, 'linearisation = "lin.toml"'))
        loaded.append(load_scenario(toml))
    plain, with_bom = loaded
    assert with_bom.sensor.linearisation == plain.sensor.linearisation and plain.sensor.linearisation
