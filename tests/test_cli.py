"""The command line: exit codes and messages at the edge."""
from __future__ import annotations

from pathlib import Path

import pytest
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


def test_demo_runs_the_scenarios_and_writes_traces_and_plots(tmp_path):
    from distctrl.cli.demo import main as demo
    results = demo(tmp_path, plate=None)          # the plate's table: test_demo_prints_the_plate_with_and_without
    assert len(results) == 3
    for r in results:
        assert r.completed and r.errors == []
    both, plain, setpos = results
    assert both.metrics["distance_error_rms"] < plain.metrics["distance_error_rms"]   # P-AXIS-00500 helps
    assert setpos.metrics["distance_error_rms"] < 0.05
    for stem in ("sheet", "sheet_plain", "dist_1"):
        assert (tmp_path / f"{stem}.csv").stat().st_size > 0 and (tmp_path / f"{stem}.png").stat().st_size > 10_000


def test_demo_output_shows_units_oscillation_and_every_collision(tmp_path, capsys):
    """make demo may not show a crashing head as "completed, no warnings" (issue 13): the plain
    CONST_DIST case is labelled as the warning example with its oscillation and collisions, every
    header keeps its [mm] (rich would swallow it as markup)."""
    from distctrl.cli.demo import main as demo

    both, plain, _ = demo(tmp_path, plate=None)
    out = capsys.readouterr().out
    assert "[mm]" in out and "WARNING EXAMPLE" in out
    assert plain.metrics["collisions"] > 0 and plain.metrics["oscillation_frequency_hz"] is not None
    assert f"900030×{plain.metrics['collisions']}" in out and " Hz, ±" in out
    assert both.metrics["collisions"] == 1 and "X = 250 mm" in out
    flat = " ".join(out.split())                    # rich wraps lines at the terminal's width
    assert "SET_POS 30 mm (%DIST_1): min true distance" in flat and "tactile probe riding on the sheet" in flat


def test_demo_prints_the_plate_with_and_without_the_functions(capsys):
    """make demo's plasma plate (issue 16; here the shortened plate): both columns, every figure with
    its unit, the collisions of the run without the functions."""
    from rich.console import Console

    from distctrl.cli.demo import plate_table
    res = plate_table(Console(width=120), "plasma_plate_short")
    out = capsys.readouterr().out
    assert "with touch_off, corner_lock, void_lock, lift" in out and "without" in out
    assert f"{res['with']['min_cut_distance_mm']:.3f} mm" in out
    assert f"{res['with']['min_distance_mm']:.3f} mm" in out and f"{res['without']['min_distance_mm']:.3f} mm" in out
    assert f"{res['with']['path_time_s']:.3f} s" in out and "SET_DIST" in out
    assert res["without"]["collisions"] > 0 and f"{res['without']['collisions']}" in out


def test_objects_lists_the_object_browser_table_for_a_scenario():
    res = CliRunner().invoke(main, ["objects", str(ROOT / "examples" / "scenarios" / "dist_1.toml"), "--axis", "Z",
                                    "--cycles", "300"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0].split()[:5] == ["No", "Axis", "Group", "Offset", "Name"]
    kp = next(line for line in lines if "DIST_CTRL::kp " in line)
    assert "0x120300" in kp and "0x33106" in kp and "REAL64" in kp and "read/write" in kp
    # the 25 objects of FCT-M3 §9.4, Fig. 34's four general axis objects and the two TF5200 aliases
    assert len([line for line in lines[2:] if line.strip()]) == 31
    assert any("m_sollw_absolut" in line for line in lines) and any("0x20300" in line for line in lines)


def test_objects_without_scenario_and_unknown_axis():
    res = CliRunner().invoke(main, ["objects"])
    assert res.exit_code == 0 and "0x13106" in res.output
    res = CliRunner().invoke(main, ["objects", "--axis", "Q"])
    assert res.exit_code == 1


def test_diag_prints_the_fig_56_block_for_the_axis():
    res = CliRunner().invoke(main, ["diag", str(ROOT / "examples" / "scenarios" / "dist_1.toml"), "--seconds", "1"])
    assert res.exit_code == 0, res.output
    for field in ("Distance Control:", "zstd: ACTIVE (2)", "sollw: 30.000000 [mm]", "Dist-Ctrl Interface:",
                  "cmd_offset:"):
        assert field in res.output


def test_diag_prints_the_3d_block_for_a_3d_channel():
    res = CliRunner().invoke(main, ["diag", str(ROOT / "examples" / "scenarios" / "app_30_60.toml"), "--seconds", "1"])
    assert res.exit_code == 0, res.output
    assert "DiagData 3D distance control" in res.output and "FCT_3D_DIST_CTRL" in res.output


@pytest.mark.parametrize("seconds, state", [(20, "ACTIVE_CONST_DIST (4)"), (24, "FREEZE (2)")])
def test_diag_3d_block_of_the_running_application_example(seconds, state):
    """Audit W3: `distctrl diag examples/scenarios/app_30_60.toml --seconds 20 / 24` showed mode SET_POS,
    sollw 0 and no sensor variable in CONST_DIST, and f_freeze 0 in FREEZE."""
    import json
    res = CliRunner().invoke(main, ["diag", str(ROOT / "examples" / "scenarios" / "app_30_60.toml"),
                                    "--seconds", str(seconds), "--json"])
    assert res.exit_code == 0, res.output
    block = json.loads(res.output)["blocks"][0]
    assert block["title"] == "DiagData 3D distance control: Kanal 1"
    sec = {k: v["value"] for s in block["sections"].values() for k, v in s.items()}
    assert sec["hli_state"] == state and sec["mode"] == "CONST_DIST (1)"
    assert sec["sollw"] == sec["set_distance"] == sec["orthogonal_set_distance"] > 0   # SET_DIST·cos θ·Lv/L
    assert sec["sollw_prog"] == 80.0 and sec["sensor_var"] == "V.E.SENSOR"
    assert sec["active_mode"] == sec["new_mode"] == "MCS (2)"
    frozen = state.startswith("FREEZE")
    assert sec["f_freeze"] == int(frozen)
    assert sec["cmd_offset_frozen"] == (sec["cmd_offset"] if frozen else 0.0) and sec["cmd_offset"] < -0.5


def test_params_checks_the_low_pass_cut_off_against_the_cycle_time(tmp_path):
    f = tmp_path / "lp.lis"
    f.write_text("kenngr.distc.filter_type LOWPASS\nkenngr.distc.low_pass_filter_fg_f0 600\n")
    res = CliRunner().invoke(main, ["params", str(f)])
    assert res.exit_code == 1 and f"{f}:2:" in res.output and "P-AXIS-00508" in res.output
    assert CliRunner().invoke(main, ["params", str(f), "--cycle-time", "0.0005"]).exit_code == 0


# ----------------------------------------------------------------------------- one exit-code table

@pytest.mark.parametrize("args", [
    ["run", "--bogus", "x.toml"],                              # unknown option (click: 2)
    ["sweep", "examples/scenarios/tune_sheet.toml", "--metric", "foo"],   # bad choice (click: 2)
    ["params", "examples"],                                    # a directory (click: 2)
    ["nosuchcommand"],                                         # unknown command (click: 2)
    ["--bogus"],                                               # unknown option of the group
    ["step", "--kp", "abc"],                                   # refused by distctrl (1)
])
def test_invalid_input_exits_1_whichever_layer_detects_it(args):
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 1, (r.exit_code, r.output)


def test_ctrl_c_in_any_command_exits_130_not_clicks_aborted_1():
    import click

    from distctrl.cli.common import DistctrlGroup

    @click.group(cls=DistctrlGroup)
    def group():
        pass

    @group.command()
    def slow():
        raise KeyboardInterrupt

    r = CliRunner().invoke(group, ["slow"])
    assert r.exit_code == 130 and "Aborted" not in r.output


def test_the_exit_codes_are_one_table():
    from distctrl.errors import ExitCode

    assert {c.name: int(c) for c in ExitCode} == {"OK": 0, "INVALID_INPUT": 1, "ABORTED": 2, "TIME_LIMIT": 3,
                                                   "CHECK_FAILED": 4, "INTERRUPTED": 130}


def test_the_command_list_shows_whole_short_helps():
    r = CliRunner().invoke(main, ["--help"])
    diag_line = next(line for line in r.output.splitlines() if line.strip().startswith("diag"))
    assert "Fig. 56" in diag_line


# ----------------------------------------------------------------------------- numeric options have ranges

def _numeric_options():
    import click

    ctx = click.Context(main)
    for name in main.list_commands(ctx):
        cmd = main.get_command(ctx, name)
        for p in cmd.params:
            if isinstance(p.type, click.types._NumberParamTypeBase):
                yield name, p


def test_every_numeric_option_of_every_command_has_a_range():
    """B2 (new-user audit): --port 70000 listened on 4464, --duration -5 was accepted. Every numeric
    option of every command is a range (a future option without one fails here), and a float option
    also refuses NaN and infinities (a bare click.FloatRange lets 'nan' through)."""
    import click

    options = list(_numeric_options())
    assert len(options) > 30            # the walk sees the lazy commands too
    no_range, lets_through = [], []
    for name, p in options:
        t = p.type
        if not isinstance(t, click.types._NumberRangeBase) or (t.min is None and t.max is None):
            no_range.append(f"{name} --{p.name}")
            continue
        if isinstance(t, click.types.FloatParamType):
            for text in ("nan", "inf", "-inf"):
                try:
                    t.convert(text, p, None)
                except click.BadParameter:
                    continue
                lets_through.append(f"{name} --{p.name} {text}")
    assert no_range == [], f"numeric options without a range: {no_range}"
    assert lets_through == [], f"float options taking a non-finite value: {lets_through}"


@pytest.mark.parametrize("args, words", [
    (["--port", "70000"], "70000"),
    (["--port", "-1"], "-1"),
    (["--duration", "-5"], "-5"),
    (["--duration", "nan"], "nan"),
])
def test_serve_refuses_an_out_of_range_port_or_duration_with_exit_1(args, words):
    r = CliRunner().invoke(main, ["serve", str(ROOT / "examples" / "scenarios" / "serve_z.toml"), "--no-discovery",
                                  *args])
    assert r.exit_code == 1, r.output
    assert words in r.stderr and "listening" not in r.output


# ----------------------------------------------------------------------------- --json on an error (R12)

def test_json_error_object_on_stdout_for_invalid_input(tmp_path):
    """R12: on invalid input `--json` left stdout empty. Now the error object is on stdout (one
    shape for every command) and the one-line message stays on stderr."""
    import json

    bad = tmp_path / "bad.toml"
    bad.write_text("durration = 3\n")
    r = CliRunner().invoke(main, ["run", str(bad), "--json"])
    assert r.exit_code == 1
    doc = json.loads(r.stdout)
    assert doc == {"command": "run", "outcome": "error", "exit_code": 1, "error": doc["error"]}
    assert "durration" in doc["error"]
    assert r.stderr.strip().splitlines() == [f"error: {doc['error']}"]


@pytest.mark.parametrize("args", [
    ["serve", "examples/scenarios/serve_z.toml", "--port", "70000", "--json"],     # a usage error (click)
    ["params", "nosuchfile.lis", "--json"],
    ["filters", "NOSUCHFILTER", "--json"],
    ["identify", "nosuch.csv", "--command", "a", "--actual", "b", "--sensor", "c", "--json"],
    ["plot", "nosuch.csv", "--json"],
    ["step", "--kp", "abc", "--json"],
    ["margins", "nosuch.toml", "--json"],
    ["calibrate", "nosuch.toml", "--json"],
    ["objects", "--axis", "Q", "--json"],
    ["diag", "nosuch.toml", "--json"],
])
def test_every_command_answers_an_error_in_json_with_the_same_shape(args):
    import json

    r = CliRunner().invoke(main, args)
    assert r.exit_code == 1, r.output
    doc = json.loads(r.stdout)
    assert set(doc) == {"command", "outcome", "exit_code", "error"}
    assert doc["command"] == args[0] and doc["outcome"] == "error" and doc["exit_code"] == 1 and doc["error"]
    assert "error" in r.stderr.lower() and "Traceback" not in r.output


# ----------------------------------------------------------------------------- unwritable outputs (R4)

needs_dev_full = pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
SHEET = str(ROOT / "examples" / "scenarios" / "dist_1.toml")


@needs_dev_full
@pytest.mark.parametrize("args, path, reason", [
    (["run", SHEET, "--trace", "/dev/full/x.csv"], "/dev/full/x.csv", "Not a directory"),
    (["run", SHEET, "--plot", "/dev/full/x.png"], "/dev/full/x.png", "Not a directory"),
    (["run", SHEET, "--report", "/dev/full/rep"], "/dev/full/rep", "Not a directory"),
    (["calibrate", str(ROOT / "examples" / "scenarios" / "calibrate_capacitive.toml"), "--out", "/dev/full/t.toml"],
     "/dev/full/t.toml", "Not a directory"),
    (["filters", "MOVING_AVERAGE:n_cycles=4", "--plot", "/dev/full/f.png"], "/dev/full/f.png", "Not a directory"),
    (["filters", "MOVING_AVERAGE:n_cycles=4", "--csv", "/dev/full"], "/dev/full", "No space left on device"),
    (["step", "--kp", "0.5", "--plot", "/dev/full/s.png"], "/dev/full/s.png", "Not a directory"),
])
def test_an_unwritable_output_is_one_line_naming_the_path_and_the_real_reason(args, path, reason):
    """R4: "/dev/full/x.csv" said "File exists" (mkdir's words for /dev/full), --csv /dev/full said
    errno 28 without the path. Every command now says the path and the real reason."""
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 1, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    assert path in lines[0] and reason in lines[0] and "File exists" not in lines[0] and "Errno" not in lines[0]


def test_plot_to_an_unwritable_output_names_the_path_and_the_reason(tmp_path):
    r = CliRunner().invoke(main, ["run", SHEET, "--trace", str(tmp_path / "t.csv")])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["plot", str(tmp_path / "t.csv"), "-o", str(tmp_path / "t.csv" / "p.png")])
    assert r.exit_code == 1
    assert r.stderr.strip() == f"error: cannot write the plot {tmp_path / 't.csv' / 'p.png'}: Not a directory " \
                               f"({tmp_path / 't.csv'} is not a folder)"


def _busy_port():
    import socket

    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.bind(("127.0.0.1", 0))
    s.listen(1)
    return s, s.getsockname()[1]


def test_serve_on_a_busy_port_names_the_address():
    s, port = _busy_port()
    try:
        r = CliRunner().invoke(main, ["serve", str(ROOT / "examples" / "scenarios" / "serve_z.toml"),
                                      "--no-discovery", "--port", str(port), "--duration", "1"])
    finally:
        s.close()
    assert r.exit_code == 1, r.output
    assert f"127.0.0.1:{port}" in r.stderr and "Address already in use" in r.stderr and "Errno" not in r.stderr


def test_serve_on_an_address_this_machine_lacks_names_it():
    r = CliRunner().invoke(main, ["serve", str(ROOT / "examples" / "scenarios" / "serve_z.toml"),
                                  "--no-discovery", "--host", "10.9.9.9", "--port", "0", "--duration", "1"])
    assert r.exit_code == 1, r.output
    assert "10.9.9.9:0" in r.stderr and "Errno" not in r.stderr


# ----------------------------------------------------------------------------- every command has --json (M4)

def test_every_command_has_json():
    """M4: the README says every command has --json; plot and demo had none."""
    import click

    ctx = click.Context(main)
    commands = []
    for name in main.list_commands(ctx):
        cmd = main.get_command(ctx, name)
        if isinstance(cmd, click.Group):      # a group (machine): each of its commands
            sub = click.Context(cmd)
            commands += [(f"{name} {s}", cmd.get_command(sub, s)) for s in cmd.list_commands(sub)]
        else:
            commands.append((name, cmd))
    missing = [name for name, cmd in commands if not any("--json" in getattr(p, "opts", ()) for p in cmd.params)]
    assert missing == []
    assert any(name == "machine write" for name, _ in commands)


def test_plot_json_says_what_it_wrote(tmp_path):
    import json

    r = CliRunner().invoke(main, ["run", SHEET, "--trace", str(tmp_path / "t.csv")])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["plot", str(tmp_path / "t.csv"), "--json", "--signals", "Z.act", "--from", "0.5"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["output"] == str(tmp_path / "t.png") and doc["format"] == "png"
    assert doc["bytes"] == (tmp_path / "t.png").stat().st_size > 1000
    assert doc["signals"] == ["Z.act"] and doc["from_s"] == 0.5 and doc["to_s"] is None


def test_demo_json_gives_the_tables_figures(tmp_path, capsys):
    import json

    from distctrl.cli.demo import main as demo

    results = demo(tmp_path, plate="plasma_plate_short", as_json=True)
    doc = json.loads(capsys.readouterr().out)             # nothing but the one object on stdout
    assert doc["command"] == "demo" and [r["label"] for r in doc["runs"]][0].startswith("CONST_DIST")
    for run, r in zip(doc["runs"], results):
        assert run["metrics"]["min_distance_mm"] == r.metrics["min_distance_mm"]
        assert run["outcome"] == r.outcome and Path(run["trace"]).is_file()
    plate = doc["plate"]
    assert plate["without"]["collisions"] > 0 and plate["with"]["collisions"] == 0
    for key in ("min_distance_mm", "min_cut_distance_mm", "time_below_half_s", "path_time_s", "set_distance_mm"):
        assert isinstance(plate["with"][key], float), key


def test_demo_says_why_a_probe_below_zero_is_no_collision():
    """new-user audit R15: the SET_POS column showed a min true distance of -0.016 mm with 0 collisions
    without a word. The tool of %DIST_1 is a tactile probe riding on the sheet: its tip may be pressed
    into its stroke (the scenario's sensor.collision_depth, 1 mm) before a contact counts (docs/run.md
    "Collisions"); the demo says so in one footnote line, with the figures of the run."""
    from distctrl.cli.demo import EXAMPLES, probe_footnote
    from distctrl.sim import run
    from distctrl.sim.scenario import load_scenario

    sc = load_scenario(EXAMPLES / "dist_1.toml")
    r = run(sc)
    m = r.metrics
    assert m["min_distance_mm"] < 0 and m["collisions"] == 0 and sc.sensor.collision_depth == 1.0
    line = probe_footnote("SET_POS 30 mm (%DIST_1)", r, sc)
    assert "\n" not in line and line.startswith("SET_POS 30 mm (%DIST_1)")
    assert f"{m['min_distance_mm']:.3f} mm" in line and "tactile probe" in line
    assert "−1 mm" in line and "collision_depth" in line and "docs/run.md" in line
    # a nozzle (collision depth 0) or a run without a negative distance gets no footnote
    sheet = load_scenario(EXAMPLES / "const_dist_sheet.toml")
    assert probe_footnote("sheet", run(sheet), sheet) is None
