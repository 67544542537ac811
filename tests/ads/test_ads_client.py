"""ads-client (npm, pinned in tests/ads/node/package.json) as a real second ADS client, in its default
mode, against the served machine (issue 14): connect, device info, read/write by symbol name
(primitives and the state_r structure), the HLI handshake ON -> ACTIVE -> OFF, handles, sum
commands, notifications, PLC stop/start, the error codes of the failure cases, disconnect.

`make test` installs Node.js/npm (Debian) and the package (`npm ci`); without them this test fails
and says how to install them: it never skips.
"""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from distctrl.ads import errors as E
from distctrl.ads.devices import serve_over_ads
from distctrl.sim.scenario import load_scenario

from . import wait_for

NODE_DIR = Path(__file__).resolve().parent / "node"
SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
INSTALL = "run `make test` (it installs nodejs and npm from Debian, then `npm ci` in tests/ads/node)"


def node() -> str:
    exe = shutil.which("node")
    if exe is None:
        pytest.fail(f"Node.js is not installed: {INSTALL}")
    if not (NODE_DIR / "node_modules" / "ads-client" / "package.json").is_file():
        pytest.fail(f"the npm package ads-client is not installed in {NODE_DIR}: {INSTALL}")
    return exe


@pytest.fixture(scope="module")
def session():
    """One whole ads-client session; the steps' results, keyed by step (see node/session.js)."""
    exe = node()
    with serve_over_ads(load_scenario(SCN / "serve_z.toml"), port=0) as served:
        proc = subprocess.run([exe, "session.js", str(served.services["ads"].server.port), "2"], cwd=NODE_DIR,
                              capture_output=True, text=True, timeout=120)
        closed_cleanly = wait_for(lambda: served.services["ads"].server.connections == 0)
    assert proc.returncode == 0, proc.stderr
    steps = json.loads(proc.stdout.strip().splitlines()[-1])
    steps["_server_connections_after"] = closed_cleanly
    return steps


def ok(steps: dict, name: str):
    step = steps[name]
    assert step["ok"], f"{name}: {step}"
    return step["value"]


def test_default_connect_reads_the_target_as_a_twincat_3_plc(session):
    assert ok(session, "connect")["connected"] is True
    assert ok(session, "system_state") == "Run"           # port 10000, extended state
    assert ok(session, "device_info") == "distctrl PLC"
    assert ok(session, "runtime_state") == "Run"          # 0xF100 by notification
    assert ok(session, "symbol_version") == 1             # 0xF008


def test_reads_by_symbol_name_decode_primitives_and_structures(session):
    assert ok(session, "read_bool") is False
    state = ok(session, "read_struct")
    assert set(state) == {"actual_state", "actual_position", "actual_offset", "command_source", "actual_distance"}
    assert state["actual_state"] == 0
    assert abs(ok(session, "read_dint") - state["actual_position"]) < 1000     # 0.1 µm, same surface
    assert set(ok(session, "read_channel_status")) == {"virt_tool_length_r", "inclination_r"}
    t = ok(session, "data_type")
    assert t["size"] == 20 and t["members"][0] == ["actual_state", "UDINT", 0]


def test_writes_by_symbol_name(session):
    assert ok(session, "variables") == ["V.E.SENSOR_GAIN"]
    assert ok(session, "write_lreal") == 2.5


def test_the_hli_handshake_on_active_off(session):
    on = ok(session, "on")
    assert on["actual_state"] == 1 and on["command_source"] == 1        # ACTIVE, commanded by the PLC
    assert ok(session, "off")["actual_state"] == 0                      # INACTIVE


def test_handles_sum_commands_and_notifications(session):
    assert ok(session, "handle") == {"size": 4, "dataType": "UDINT", "bytes": 4}
    assert ok(session, "sum_read") == [[1, 0, 0, 0], [1]]               # ACTIVE, enable_w TRUE
    assert ok(session, "sum_handles") == [0, E.ADSERR_DEVICE_SYMBOLNOTFOUND]
    assert ok(session, "subscribe") >= 5                                # 10 ms cycle for 300 ms
    struct_sub = ok(session, "subscribe_struct")                        # a structure by notification
    assert struct_sub["count"] >= 1 and struct_sub["fields"][0] == "actual_state"


def test_failure_cases_answer_twincat_error_codes(session):
    assert session["unknown_symbol"]["code"] == E.ADSERR_DEVICE_SYMBOLNOTFOUND       # 0x710
    assert session["read_only"]["code"] == E.ADSERR_DEVICE_INVALIDACCESS             # 0x704
    assert session["unknown_type_raw"]["code"] == E.ADSERR_DEVICE_SYMBOLNOTFOUND     # 0x710
    assert not session["unknown_type"]["ok"]


def test_the_cnc_port_in_default_mode(session):
    assert ok(session, "cnc_port") > 0                                  # DIST_CTRL::kp of axis 2 (Z)


def test_plc_stop_and_start_and_a_clean_disconnect(session):
    assert ok(session, "stop_plc") == {"stopped": True, "running": True, "connected": True}
    assert ok(session, "disconnect") is False
    assert session["_server_connections_after"], "the server still holds the client's connection"
