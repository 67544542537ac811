"""``distctrl identify`` on the command line: --json keys, --out files, exit codes, messages."""
from __future__ import annotations

import json
import subprocess
import sys
import tomllib

import pytest
from click.testing import CliRunner

from distctrl.cli import main
from tests.workbench.identify_plants import (Plant, chirp_command, ramp_command, simulate, steps_command, write_csv,
                                             write_scope_csv)

PLANT = Plant(resonance_hz=0.0)          # rigid: the written scenario runs on today's simulator
ARGS = ["--command", "set_pos", "--actual", "act_pos", "--sensor", "sensor"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("identify")
    out = {}
    for i, (name, cmd) in enumerate([("steps", steps_command(seconds=8.0)), ("chirp", chirp_command(seconds=10.0)),
                                     ("ramp", ramp_command(seconds=12.0, surface=PLANT.surface))]):
        p = d / f"{name}.csv"
        write_csv(p, *simulate(PLANT, cmd, seed=i))
        out[name] = p
    return out


def run(args):
    return CliRunner().invoke(main, ["identify", *map(str, args)], catch_exceptions=False)


def test_json_keys_exactly_and_out_files(files, tmp_path):
    out = tmp_path / "fitted"
    r = run([files["steps"], files["chirp"], files["ramp"], *ARGS, "--surface", PLANT.surface, "--json",
             "--out", out])
    assert r.exit_code == 0, r.output
    j = json.loads(r.stdout)
    assert set(j["drive"]) == {"kv", "dead_time", "feedforward", "v_max", "a_max", "resonance_hz", "damping"}
    assert set(j["sensor"]) == {"delay", "noise_std", "characteristic"}
    assert abs(j["drive"]["kv"] / PLANT.kv - 1) <= 0.1
    assert j["drive"]["resonance_hz"] is None and any("no resonance" in w for w in j["warnings"])
    assert (out / "fitted.toml").is_file() and (out / "report.html").is_file() and (out / "identify.png").is_file()
    doc = tomllib.loads((out / "fitted.toml").read_text())
    z = doc["axes"]["Z"]
    assert z["bus_delay_cycles"] == 3 and "resonance_hz" not in z
    assert doc["sensor"]["delay_cycles"] == 2 and len(doc["sensor"]["characteristic"]) > 10
    assert "data:image/png;base64," in (out / "report.html").read_text()
    # the written scenario runs
    from distctrl.sim.runner import run as run_scenario
    from distctrl.sim.scenario import load_scenario

    result = run_scenario(load_scenario(out / "fitted.toml"), progress=False)
    assert result.completed and not result.errors


def test_summary_has_units(files):
    r = run([files["steps"], files["chirp"], *ARGS])
    assert r.exit_code == 0, r.output
    for text in ("1/s", "ms", "mm/s", "mm/s^2", "um", "characteristic -"):
        assert text in r.stdout
    assert "--surface" in r.stderr


def test_scope_export_on_the_command_line(files, tmp_path):
    import numpy as np

    t, c, a, s = (np.loadtxt(files["steps"], delimiter=",", skiprows=1, unpack=True))
    p = tmp_path / "scope.csv"
    write_scope_csv(p, t, c, a, s)
    r = run([p, "--command", "MAIN.fSetPos", "--actual", "MAIN.fActPos", "--sensor", "MAIN.fDistance", "--json"])
    assert r.exit_code == 0, r.output
    j = json.loads(r.stdout)
    assert j["recordings"][0]["source"] == "scope" and abs(j["drive"]["dead_time"] - PLANT.dead_time) <= 0.001


@pytest.mark.parametrize("args, message", [
    (["missing.csv", *ARGS], "no such file"),
    (["{steps}", "--command", "set_pos", "--actual", "act_pos", "--sensor", "gap"],
     "no sensor column 'gap'.*columns: time, set_pos, act_pos, sensor"),
    (["{steps}", *ARGS, "--surface", "1", "--calibrated-at", "1"], "give one of them"),
    (["{steps}", *ARGS, "--value-unit", "inches"], "unit 'inches' not known"),
])
def test_errors_exit_1(files, args, message):
    args = [a.format(**files) for a in args]
    r = run(args)
    assert r.exit_code == 1
    import re

    assert re.search(message, r.stderr), r.stderr
    assert "Traceback" not in r.output


def test_no_excitation_exit_1(tmp_path):
    import numpy as np

    t = np.arange(3000) * 0.001
    z = np.full(t.size, 11.0)
    p = tmp_path / "still.csv"
    write_csv(p, t, z, z, z - 10)
    r = run([p, *ARGS])
    assert r.exit_code == 1 and "excitation too poor" in r.stderr and "record steps" in r.stderr


def test_help_says_what_to_record():
    r = subprocess.run([sys.executable, "-m", "distctrl", "identify", "--help"], capture_output=True, text=True)
    assert r.returncode == 0
    for text in ("chirp", "1-150 Hz", "encoder", "ramp", "--out"):
        assert text in r.stdout


def test_resonant_plant_scenario_runs(tmp_path):
    """The written scenario with resonance_hz and damping is accepted by distctrl run (resonant drive)."""
    plant = Plant()                                            # 40 Hz, zeta 0.05
    files = []
    for i, (name, cmd) in enumerate([("steps", steps_command(seconds=6.0)), ("chirp", chirp_command(seconds=12.0)),
                                     ("ramp", ramp_command(seconds=10.0, surface=plant.surface))]):
        p = tmp_path / f"{name}.csv"
        write_csv(p, *simulate(plant, cmd, seed=i))
        files.append(p)
    out = tmp_path / "fitted"
    r = run([*files, *ARGS, "--surface", plant.surface, "--out", out])
    assert r.exit_code == 0, r.output
    z = tomllib.loads((out / "fitted.toml").read_text())["axes"]["Z"]
    assert abs(z["resonance_hz"] / 40.0 - 1) <= 0.1 and 0.025 <= z["damping"] <= 0.075
    res = subprocess.run([sys.executable, "-m", "distctrl", "run", str(out / "fitted.toml"), "--json"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["completed"]


def test_a_parquet_trace_reads_as_its_csv_twin(files, tmp_path):
    """R5 (new-user audit): a Parquet trace (`run --trace x.parquet`) was read as text ("no command
    column 'Z.cmd'; columns: PAR1..."). It is read as the trace it is: the same figures as its CSV."""
    pytest.importorskip("pyarrow")
    import numpy as np

    from distctrl.trace import Trace
    from distctrl.trace.parquet import to_parquet

    args = []
    for name in ("steps", "chirp", "ramp"):
        raw = np.genfromtxt(files[name], delimiter=",", names=True)
        cols = list(raw.dtype.names)
        tr = Trace(cols, np.column_stack([raw[c] for c in cols]), units={"t": "s", "set_pos": "mm", "act_pos": "mm",
                                                                        "sensor": "mm"})
        tr.to_csv(tmp_path / f"{name}.csv")
        to_parquet(tr, tmp_path / f"{name}.parquet")
        args.append(name)
    common = [*ARGS, "--surface", PLANT.surface, "--json"]
    a = run([*(tmp_path / f"{n}.csv" for n in args), *common])
    b = run([*(tmp_path / f"{n}.parquet" for n in args), *common])
    assert a.exit_code == 0 and b.exit_code == 0, b.output
    ja, jb = json.loads(a.stdout), json.loads(b.stdout)
    assert ja["drive"] == jb["drive"] and ja["sensor"] == jb["sensor"]
    assert ja["drive"]["kv"] is not None


def test_an_identification_answers_to_dict_as_json_and_plots_itself(files, tmp_path):
    """The result face of python-control's results: to_dict() is what --json prints, plot() the figure
    of the report (a Figure on an Agg canvas: per recording motor and sensor, then the frequency
    response and the characteristic)."""
    import warnings

    from distctrl.cli.common import json_text
    from distctrl.workbench.identify import identify, load_signals

    r = run([files["steps"], files["chirp"], *ARGS, "--json"])
    assert r.exit_code == 0, r.output
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify([load_signals(files[k], command="set_pos", actual="act_pos", sensor="sensor")
                        for k in ("steps", "chirp")])
    assert json.loads(json_text(res.to_dict())) == json.loads(r.stdout)
    fig = res.plot(tmp_path / "id.png")
    assert (tmp_path / "id.png").read_bytes()[:4] == b"\x89PNG"
    assert type(fig.canvas).__name__ == "FigureCanvasAgg"
    assert len(fig.axes) == 2 * 3 + 1                                   # 2 recordings + the last row, a phase twin
    motor, sensor = fig.axes[0], fig.axes[1]
    assert [ln.get_label() for ln in motor.get_lines()] == ["actual (measured)", "drive model", "command"]
    assert [ln.get_label() for ln in sensor.get_lines()] == ["sensor (measured)", "sensor model"]
