"""`distctrl objects`, `params` and `plot` as a user meets them (issue 13): English headers with the
axis and mm values, state names, --json, --watch against a served machine; channel lists in params;
Parquet traces and .jpg in plot."""
from __future__ import annotations

import gc
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from distctrl.cli import main
from distctrl.errors import ExitCode
from tests.ads import port_free

ROOT = Path(__file__).resolve().parents[2]
SCN = ROOT / "examples" / "scenarios"


def _objects(*args):
    res = CliRunner().invoke(main, ["objects", *args])
    assert res.exit_code == 0, res.output
    return res.output


def test_objects_show_the_axis_the_value_in_mm_and_the_state_name():
    out = _objects(str(SCN / "dist_1.toml"), "--axis", "Z", "--cycles", "2000")
    head, *_ = out.splitlines()
    assert head.split() == ["No", "Axis", "Group", "Offset", "Name", "Type", "Length", "Unit", "Raw", "value",
                            "Value", "Access"]
    state = next(line for line in out.splitlines() if "DIST_CTRL::state " in line)
    assert " 3 Z " in state and state.split()[-2] == "ACTIVE"
    setpos = next(line for line in out.splitlines() if "DIST_CTRL::set_pos " in line)
    assert "3000000000" in setpos and "30 mm" in setpos                 # 0.01 nm beside mm
    vmax = next(line for line in out.splitlines() if "DIST_CTRL_PARAM[0]::v_max " in line)
    assert "µm/s" in vmax and "mm/s" in vmax.split("µm/s", 1)[1]


def test_objects_json_is_one_object_with_raw_and_converted_values():
    js = json.loads(_objects(str(SCN / "dist_1.toml"), "--axis", "Z", "--cycles", "2000", "--json"))
    by_name = {o["name"]: o for o in js["objects"]}
    assert by_name["DIST_CTRL::set_pos"]["raw_value"] == 3_000_000_000
    assert by_name["DIST_CTRL::set_pos"]["value"] == "30 mm"
    assert by_name["DIST_CTRL::state"]["value"] == "ACTIVE" and by_name["DIST_CTRL::kp"]["axis"] == "3 Z"


HOST, NET_ID = "127.0.0.4", "127.0.0.4.1.1"


def test_objects_watch_reads_a_served_machine_over_ads():
    pytest.importorskip("pyads")
    if not port_free(HOST, 48898):
        pytest.skip("TCP 48898 is in use on this address")
    from distctrl.ads.devices import serve_over_ads
    from distctrl.sim.scenario import load_scenario

    gc.collect()
    gc.freeze()
    try:
        with serve_over_ads(load_scenario(SCN / "serve_z.toml"), host=HOST, net_id=NET_ID) as served:
            served.machine.hli["Z"].plc_command("ON_CONST_DIST", 1.0)
            res = CliRunner().invoke(main, ["objects", str(SCN / "serve_z.toml"), "--watch", "--host", HOST,
                                            "--net-id", NET_ID, "--count", "2", "--interval", "0.3",
                                            "--axis", "Z", "--json"])
    finally:
        gc.unfreeze()
    assert res.exit_code == 0, res.output
    refreshes = [json.loads(line) for line in res.output.splitlines() if line.strip()]
    assert [r["refresh"] for r in refreshes] == [1, 2]
    last = {o["name"]: o for o in refreshes[-1]["objects"]}
    assert last["DIST_CTRL::state"]["axis"] == "2 Z" and last["DIST_CTRL::state"]["value"] == "ACTIVE"
    assert last["DIST_CTRL::set_distance"]["value"] == "1 mm"
    assert last["DIST_CTRL::filter_type"]["raw_value"]                  # the STRING object reads too


def test_objects_watch_without_a_server_is_one_line():
    pytest.importorskip("pyads")
    res = CliRunner().invoke(main, ["objects", "--watch", "--host", "127.0.0.5", "--net-id", "127.0.0.5.1.1",
                                    "--count", "1"])
    assert res.exit_code == ExitCode.INVALID_INPUT and res.stderr.startswith("error: ")
    assert len(res.stderr.strip().splitlines()) == 1


def test_params_validates_a_channel_list_and_names_line_and_range(tmp_path):
    res = CliRunner().invoke(main, ["params", str(SCN / "channel_3d.lis")])
    assert res.exit_code == 0, res.output
    assert "dist_ctrl[0].kp" in res.output and "P-CHAN-00821" in res.output
    bad = tmp_path / "c.lis"
    bad.write_text("configuration.decoder.function FCT_3D_DIST_CTRL\ndist_ctrl[0].kp 7\n")
    res = CliRunner().invoke(main, ["params", str(bad)])
    assert res.exit_code == 1 and f"{bad}:2:" in res.stderr and "P-CHAN-00821" in res.stderr
    nyq = tmp_path / "n.lis"
    nyq.write_text("dist_ctrl[0].filter_type LOWPASS\ndist_ctrl[0].low_pass_filter_fg_f0 900\n")
    res = CliRunner().invoke(main, ["params", str(nyq)])
    assert res.exit_code == 1 and f"{nyq}:2:" in res.stderr and "P-CHAN-00817" in res.stderr


def test_params_json(tmp_path):
    res = CliRunner().invoke(main, ["params", str(SCN / "z_probe.lis"), "--json"])
    assert res.exit_code == 0, res.output
    js = json.loads(res.output)
    assert js["kind"] == "axis" and js["valid"] is True
    assert all({"key", "id", "value", "unit", "description"} <= set(p) for p in js["parameters"])
    js = json.loads(CliRunner().invoke(main, ["params", str(SCN / "channel_3d.lis"), "--json", "--all"]).output)
    assert js["kind"] == "channel" and any(p["id"] == "P-CHAN-00821" for p in js["parameters"])


def test_plot_reads_the_parquet_trace_that_run_writes_and_writes_jpg(tmp_path):
    pytest.importorskip("pyarrow")
    trace = tmp_path / "t.parquet"
    assert CliRunner().invoke(main, ["run", str(SCN / "dist_1.toml"), "--trace", str(trace), "--json"]).exit_code == 0
    out = tmp_path / "p.jpg"
    res = CliRunner().invoke(main, ["plot", str(trace), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert out.read_bytes()[:3] == b"\xff\xd8\xff"                       # JPEG


def test_diag_json_gives_numbers_with_units():
    res = CliRunner().invoke(main, ["diag", str(SCN / "dist_1.toml"), "--json"])
    assert res.exit_code == 0, res.output
    block = json.loads(res.output)["blocks"][0]
    assert block["axis"]["value"] == "Z" and block["cycle"] == {"value": 1000, "unit": "cycles"}
    values = block["sections"]["Values"]
    assert values["set_pos"] == {"value": 30.0, "unit": "mm"} and values["offset"]["unit"] == "mm"
    assert isinstance(block["logged_events"], list)
    res3d = json.loads(CliRunner().invoke(main, ["diag", str(SCN / "app_30_60.toml"), "--json"]).output)
    assert res3d["blocks"][0]["title"].startswith("DiagData 3D distance control")


def test_no_help_text_or_doc_points_users_at_the_seeds_folder():
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")), *sorted((ROOT / "distctrl").rglob("*.py"))]:
        assert "seeds/" not in path.read_text(encoding="utf-8"), path


def test_objects_watch_follows_a_served_machine_on_another_port():
    """R13 (new-user audit): objects --watch had no port option, so a machine served on another
    port than 48898 (a local TwinCAT router holds it) could not be watched. pyads's router takes
    the address as host:port: --port passes it."""
    pytest.importorskip("pyads")
    from distctrl.ads.devices import serve_over_ads
    from distctrl.sim.scenario import load_scenario

    host, net_id = "127.0.0.6", "127.0.0.6.1.1"
    gc.collect()
    gc.freeze()
    try:
        with serve_over_ads(load_scenario(SCN / "serve_z.toml"), host=host, port=0, net_id=net_id,
                           discovery_port=None) as served:
            port = served.services["ads"].server.port
            assert port != 48898
            res = CliRunner().invoke(main, ["objects", str(SCN / "serve_z.toml"), "--watch", "--host", host,
                                            "--port", str(port), "--net-id", net_id, "--count", "1",
                                            "--axis", "Z", "--json"])
    finally:
        gc.unfreeze()
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["port"] == port and {o["name"] for o in doc["objects"]} >= {"DIST_CTRL::kp", "DIST_CTRL::state"}
