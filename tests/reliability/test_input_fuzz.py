"""Fuzzing of every text input a user gives distctrl (issue 8 reliability), outcome classes counted.

Inputs: NC programs (axis dialect ``Z[DIST_CTRL ...]`` and 3D ``#DIST CTRL ...``), parameter lists
in the kernel list format (axis and channel lists) and scenario TOML files. Each is fed with
grammar-aware generated text (plausible blocks / lines / keys with random values) and with
byte-level mutations of the shipped examples (insert / delete / replace bytes, decoded with
``errors="replace"``).

Contract checked for every input:

* it is accepted, or it raises the project's documented error type for that input
  (``NcSyntaxError`` / ``ParameterError`` / ``ScenarioError``) -- no other exception escapes;
* the error names the file and the line (and for NC the column) and has a non-empty message;
  scenario *validation* errors name the key path instead of a line (by design: the TOML parser
  gives no positions for values, see ``ScenarioError``), TOML syntax errors name the line;
* accepted NC programs are also run briefly on the virtual machine: run-time problems come back
  as values (``RunResult.errors``), never as exceptions;
* every input finishes within ``MAX_SECONDS_PER_INPUT`` (measured with ``time.perf_counter``; a
  SIGALRM watchdog turns a hang into a failure instead of a stuck test run).

Figures: ``tally("fuzz_nc" | "fuzz_params" | "fuzz_scenario", inputs=, accepted=, rejected=, ran=,
runtime_error=)``.
"""
from __future__ import annotations

import dataclasses
import signal
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from distctrl.errors import DistCtrlError, ParameterError
from distctrl.nc import NcSyntaxError, Program, parse_program
from distctrl.params import AXIS_PARAMETERS, load_list, parse_list_text
from distctrl.params.channel import CHANNEL_LIST, CHANNEL_PARAMETERS
from distctrl.sim.runner import run
from distctrl.sim.scenario import ScenarioError, scenario_from_dict, scenario_from_text

from .conftest import RELIABILITY, tally

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
SCN = EXAMPLES / "scenarios"

NC_EXAMPLES = [p.read_bytes() for p in sorted(EXAMPLES.glob("*.nc")) + sorted(SCN.glob("*.nc"))]
AXIS_LISTS = [p.read_bytes() for p in [EXAMPLES / "axis_z_9_3.lis", SCN / "z_probe.lis", SCN / "z_laser.lis"]]
CHANNEL_LISTS = [p.read_bytes() for p in [EXAMPLES / "channel_3d_12_8_3.lis", SCN / "channel_3d.lis"]]
SCENARIOS = [p.read_bytes() for p in sorted(SCN.glob("*.toml"))]

#: generous bound (inputs take milliseconds, a short run ~0.1 s): catches runaways, not a busy CI box
MAX_SECONDS_PER_INPUT = 2.0
#: watchdog: a hang fails the test after this many seconds instead of blocking the suite
WATCHDOG_SECONDS = 20
#: simulated time of the brief runs of accepted programs / scenarios
RUN_SECONDS = 0.15

parse_program("")   # build the parser once, outside the timed calls


class Hang(Exception):
    """Raised by the watchdog: an input did not finish."""


@contextmanager
def bounded(what: str):
    """Time the body; fail on > MAX_SECONDS_PER_INPUT, abort it (SIGALRM) on a real hang."""
    def on_alarm(signum, frame):  # noqa: ARG001
        raise Hang(f"{what}: no result after {WATCHDOG_SECONDS} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(WATCHDOG_SECONDS)
    started = time.perf_counter()
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    elapsed = time.perf_counter() - started
    assert elapsed < MAX_SECONDS_PER_INPUT, f"{what} took {elapsed:.2f} s"


def n_lines(text: str) -> int:
    return len(text.splitlines()) or 1


# ------------------------------------------------------------------ byte-level mutation

@st.composite
def mutated(draw, originals: list[bytes]) -> str:
    """An example file with 1..8 byte edits, decoded with errors='replace'."""
    data = bytearray(draw(st.sampled_from(originals)))
    for _ in range(draw(st.integers(1, 8))):
        kind = draw(st.sampled_from(["insert", "delete", "replace", "duplicate", "flip"]))
        at = draw(st.integers(0, len(data)))
        if kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=6))
        elif kind == "delete":
            del data[at:at + draw(st.integers(1, 12))]
        elif kind == "replace":
            chunk = draw(st.binary(min_size=1, max_size=4))
            data[at:at + len(chunk)] = chunk
        elif kind == "duplicate":
            piece = data[at:at + draw(st.integers(1, 40))]
            data[at:at] = piece * draw(st.integers(1, 3))
        elif at < len(data):
            data[at] ^= 1 << draw(st.integers(0, 7))
    return bytes(data).decode("utf-8", errors="replace")


# ------------------------------------------------------------------ NC programs

NUMBERS = st.one_of(
    st.integers(-10**6, 10**6).map(str),
    st.floats(allow_nan=False, allow_infinity=False, width=32).map(lambda x: f"{x:g}"),
    st.sampled_from(["0", "0.0", "-0", "1e9", "1e-9", "1e308", "-1e308", "1e999", ".5", "5.", "-.1",
                     "30", "10", "1", "0.001", "1E3"]),
)
VARIABLES = st.sampled_from(["V.E.SENSOR", "V.E.HEIGHT", "V.E.UNDEFINED", "V.G.WZ_AKT.L", "V.E.X"])


@st.composite
def expressions(draw, depth: int = 0) -> str:
    if depth > 2 or draw(st.booleans()):
        return draw(st.one_of(NUMBERS, VARIABLES))
    op = draw(st.sampled_from(["+", "-", "*", "/", "**"]))
    left, right = draw(expressions(depth + 1)), draw(expressions(depth + 1))
    return draw(st.sampled_from([f"{left}{op}{right}", f"[{left}{op}{right}]", f"-{left}"]))


VALUE = st.one_of(NUMBERS, NUMBERS, expressions())
AXIS_FLAGS = ["ON", "OFF", "FREEZE", "DRYRUN", "CHECK_POS", "REF", "NO_MOVE", "CONST_DIST", "WAIT"]
AXIS_NUMBER_KW = ["SET_POS", "SET_DIST", "VAL1", "VAL2", "VAL3", "VAL4", "VAL5", "KP", "I_TN", "D_TV",
                  "N_CYCLES", "FG_F0", "ORDER", "SMOOTH_FACT", "KALMAN_SIGMA"]
NAME_VALUES = {"SENSOR_SOURCE": ["VARIABLE", "ENCODER", "AXIS", "SENSOR", "X", "V.E.SENSOR"],
               "SENSOR_VAR": ["V.E.SENSOR", "V.E.HEIGHT", "SENSOR", "V.G.WZ_AKT.L", "3"],
               "FILTER_TYPE": ["KALMAN_MA", "MA", "KALMAN", "PT1", "LOW_PASS", "NONE", "OFF", "BUTTER"],
               "MODE": ["ACS", "PCS", "TOOL", "OFF", "ON", "WCS"],
               "DIRECTION": ["X", "Y", "Z", "A", "TOOL", "-Z"]}
FLAGS_3D = AXIS_FLAGS + ["SURFACE"]
NUMBER_KW_3D = AXIS_NUMBER_KW + ["FILTER_TIME"]
GARBAGE_KW = st.sampled_from(["FOO", "ON=1", "=", "SET_POS=", "KP==1", "[", "]", "DIST_CTRL", "#", ";x"])


@st.composite
def keyword_args(draw, flags, number_kw, name_kw) -> list[str]:
    args = []
    for _ in range(draw(st.integers(0, 5))):
        kind = draw(st.sampled_from(["flag", "number", "name", "garbage"] if draw(st.integers(0, 9))
                                    else ["garbage"]))
        if kind == "flag":
            args.append(draw(st.sampled_from(flags)))
        elif kind == "number":
            args.append(f"{draw(st.sampled_from(number_kw))}={draw(VALUE)}")
        elif kind == "name":
            kw = draw(st.sampled_from(name_kw))
            args.append(f"{kw}={draw(st.sampled_from(NAME_VALUES[kw]))}")
        else:
            args.append(draw(GARBAGE_KW))
    return args


@st.composite
def axis_dist_ctrl(draw) -> str:
    axis = draw(st.sampled_from(["Z", "Z", "X", "Y", "A"]))
    args = draw(keyword_args(AXIS_FLAGS, AXIS_NUMBER_KW, ["SENSOR_SOURCE", "SENSOR_VAR", "FILTER_TYPE"]))
    return f"{axis}[DIST_CTRL {' '.join(args)}]"


@st.composite
def dist_ctrl_3d(draw) -> str:
    outside = draw(st.lists(st.sampled_from(["WAIT", "ON", "OFF", "FREEZE", "DRYRUN", "CHECK_POS", "REF"]),
                            max_size=2))
    args = draw(keyword_args(FLAGS_3D, NUMBER_KW_3D, list(NAME_VALUES)))
    bracket = f" [{' '.join(args)}]" if args or draw(st.booleans()) else ""
    return f"#DIST CTRL {' '.join(outside)}{bracket}".replace("  ", " ")


@st.composite
def motion(draw) -> str:
    words = draw(st.lists(st.sampled_from(["G0", "G1", "G90", "G91"]), max_size=2))
    for axis in draw(st.lists(st.sampled_from(["X", "Y", "Z", "A", "C"]), max_size=3, unique=True)):
        words.append(f"{axis}{draw(NUMBERS)}" if draw(st.booleans()) else f"{axis}={draw(VALUE)}")
    if draw(st.booleans()):
        words.append(f"F{draw(st.sampled_from(['3000', '6000', '0', '-1', '1e9']))}")
    return " ".join(words)


@st.composite
def nc_block(draw, three_d: bool) -> str:
    kinds = [axis_dist_ctrl(), motion(), st.just("M30"), st.builds(lambda v: f"#TIME {v}", NUMBERS),
             st.builds(lambda n, v: f"V.E.{n} = {v}", st.sampled_from(["SENSOR", "HEIGHT", "X"]), VALUE),
             st.just(";comment"), st.just("(paren comment)")]
    if three_d:
        kinds += [dist_ctrl_3d(), dist_ctrl_3d(),
                  st.builds(lambda i, v: f"V.G.KIN_STEP[1].ID[98].PARAM[{i}] = {v}", st.integers(-1, 5), NUMBERS),
                  st.sampled_from(["#KIN ID[9.98]", "#TRAFO ON", "#TRAFO OFF", "V.G.WZ_AKT.L = 80"])]
    body = draw(st.one_of(*kinds))
    number = f"N{draw(st.integers(0, 99999))} " if draw(st.integers(0, 4)) else ""
    comment = draw(st.sampled_from(["", "", " ;note", " (c)"]))
    return number + body + comment


@st.composite
def nc_program(draw) -> str:
    three_d = draw(st.booleans())
    blocks = draw(st.lists(nc_block(three_d), min_size=1, max_size=8))
    if draw(st.booleans()):
        blocks.insert(0, "%FUZZ")
    if draw(st.integers(0, 3)):
        blocks.append("N999 M30")
    return draw(st.sampled_from(["\n", "\r\n"])).join(blocks) + draw(st.sampled_from(["", "\n"]))


AXIS_SCENARIO = {"name": "fuzz", "duration": RUN_SECONDS, "settle_time": 0.0,
                 "variables": {"SENSOR": 1.0, "HEIGHT": 2.0},
                 "axes": {"X": {"v_max": 300.0, "a_max": 3000.0}, "Y": {},
                          "Z": {"params": "z_probe.lis", "start": 30.0, "kv": 50.0}},
                 "surface": {"base": 29.7},
                 "sensor": {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0}}
SCENARIO_3D = {"name": "fuzz3d", "duration": RUN_SECONDS, "settle_time": 0.0,
               "channel": {"params": "../channel_3d_12_8_3.lis", "kinematics": "none"},
               "axes": {"X": {}, "Y": {}, "Z": {"start": 10.0, "kv": 50.0, "feedforward": 1.0}},
               "surface": {"base": 8.8},
               "sensor": {"kind": "distance", "mode": "orthogonal_clamping_point", "variable": "SENSOR",
                          "range_max": 150.0}}


def check_nc(text: str) -> None:
    """Parse; if accepted, run briefly. Only NcSyntaxError may escape parsing, nothing may escape running."""
    tally("fuzz_nc", inputs=1)
    with bounded("parse"):
        try:
            program = parse_program(text, "fuzz.nc")
        except NcSyntaxError as exc:
            program = None
            assert exc.file == "fuzz.nc"
            assert exc.message and not exc.message.startswith("internal parser error"), exc.message
            assert exc.line is not None and 1 <= exc.line <= n_lines(text) + 1, (exc.line, str(exc))
            assert exc.column is not None and exc.column >= 1, str(exc)
    if program is None:
        tally("fuzz_nc", rejected=1)
        return
    assert isinstance(program, Program)
    tally("fuzz_nc", accepted=1)
    base = SCENARIO_3D if "#DIST" in text.upper() or "#KIN" in text.upper() else AXIS_SCENARIO
    scenario = scenario_from_dict({**base, "program_text": text}, base_dir=SCN, source="fuzz.toml")
    with bounded("run"):
        result = run(scenario, keep_trace=False)
    tally("fuzz_nc", ran=1)
    if result.errors or result.aborted:
        tally("fuzz_nc", runtime_error=1)
        for err in result.errors:
            assert err.get("message"), err


@RELIABILITY
@given(nc_program())
def test_nc_generated_programs(text):
    check_nc(text)


@RELIABILITY
@given(mutated(NC_EXAMPLES))
def test_nc_mutated_examples(text):
    check_nc(text)


def test_nc_examples_themselves_run():
    for data in NC_EXAMPLES:
        check_nc(data.decode("utf-8"))


# ------------------------------------------------------------------ parameter lists

AXIS_KEYS = sorted({k for s in AXIS_PARAMETERS for k in (s.key, *s.aliases)})
CHANNEL_KEYS = sorted({k for s in CHANNEL_PARAMETERS for k in (s.key, *s.aliases)})
LIST_VALUES = st.one_of(
    st.integers(-2**40, 2**40).map(str),
    st.integers(-3, 100).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["0", "1", "2", "-1", "0.5", "1e3", "1e400", "nan", "inf", "-inf", "0x10", "1_000",
                     "KALMAN_MA", "KALMAN", "MA", "PT1", "LOW_PASS", "NONE", "TRUE", "", "1 2", "#1"]),
)


@st.composite
def list_text(draw, keys: list[str]) -> str:
    lines = []
    for _ in range(draw(st.integers(0, 10))):
        kind = draw(st.integers(0, 19))
        if kind == 0:
            lines.append(draw(st.text(max_size=30)))                       # anything
        elif kind == 1:
            lines.append("# " + draw(st.text(max_size=20)))                # comment line
        elif kind == 2:
            key = draw(st.sampled_from(keys))
            lines.append(key.replace("[0]", f"[{draw(st.integers(0, 3))}]") + " " + draw(LIST_VALUES))
        elif kind == 3:
            lines.append(draw(st.sampled_from(keys)))                      # missing value
        else:
            key = draw(st.sampled_from(keys))
            pad = " " * draw(st.integers(1, 20))
            comment = draw(st.sampled_from(["", "", "  # comment", "# x", "\t# [0.1µm] unit"]))
            lines.append(f"{key}{pad}{draw(LIST_VALUES)}{comment}")
    return draw(st.sampled_from(["\n", "\r\n"])).join(lines)


def check_params(text: str, *, channel: bool) -> None:
    tally("fuzz_params", inputs=1)
    kwargs = {"fmt": CHANNEL_LIST} if channel else {}
    with bounded("parse_list_text"):
        try:
            parse_list_text(text, "fuzz.lis", **kwargs)
        except ParameterError as exc:
            tally("fuzz_params", rejected=1)
            assert exc.file == "fuzz.lis", str(exc)
            assert exc.line is not None and 1 <= exc.line <= n_lines(text), (exc.line, str(exc))
            assert str(exc).strip() and str(exc).startswith(f"fuzz.lis:{exc.line}: "), str(exc)
        else:
            tally("fuzz_params", accepted=1)


@RELIABILITY
@given(list_text(AXIS_KEYS))
def test_axis_list_generated(text):
    check_params(text, channel=False)


@RELIABILITY
@given(list_text(CHANNEL_KEYS))
def test_channel_list_generated(text):
    check_params(text, channel=True)


@RELIABILITY
@given(mutated(AXIS_LISTS))
def test_axis_list_mutated(text):
    check_params(text, channel=False)


@RELIABILITY
@given(mutated(CHANNEL_LISTS))
def test_channel_list_mutated(text):
    check_params(text, channel=True)


_TMP = tempfile.TemporaryDirectory(prefix="distctrl-fuzz-")


@RELIABILITY
@given(st.sampled_from(AXIS_LISTS + CHANNEL_LISTS), st.binary(max_size=40), st.integers(0, 2000))
def test_load_list_raw_bytes(original, junk, at):
    """load_list on a file with raw (possibly non-UTF-8) bytes spliced in: the file path is named."""
    path = Path(_TMP.name) / "fuzz.lis"
    path.write_bytes(original[:at] + junk + original[at:])
    channel = original in CHANNEL_LISTS
    tally("fuzz_params", inputs=1)
    with bounded("load_list"):
        try:
            load_list(path, **({"fmt": CHANNEL_LIST} if channel else {}))
        except ParameterError as exc:
            tally("fuzz_params", rejected=1)
            assert exc.file == str(path) and exc.line is not None and str(exc).strip(), str(exc)
        else:
            tally("fuzz_params", accepted=1)


# ------------------------------------------------------------------ scenarios

TOML_VALUES = st.one_of(
    st.integers(-10**6, 10**6).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(lambda x: {"nan": "nan", "inf": "inf",
                                                                  "-inf": "-inf"}.get(repr(x), repr(x))),
    st.sampled_from(['"Z"', '"X"', '"Q"', '""', '"encoder"', '"distance"', '"step"', '"sine"', "true", "false",
                     "[]", "{}", "[1, 2]", '"z_probe.lis"', '"../dist_1.nc"', '"missing.nc"', '"../dist3d_1.nc"',
                     '"none"', '"CA"', "0", "1e-5", "0.1", "1e300", '"ON"', '"OFF"', '"REF"', "-1"]),
    st.text(max_size=8).map(lambda s: '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'),
)
SCENARIO_KEYS = ["name", "cycle_time", "duration", "settle_time", "seed", "tool_length", "start", "kv",
                 "v_max", "a_max", "feedforward", "axis", "kind", "range_min", "range_max", "noise_std", "base",
                 "mode", "variable", "bus_delay_cycles", "resolution", "params", "program", "program_text",
                 "t", "unknown_key"]
SCENARIO_HEADERS = ["[axes.X]", "[axes.Z]", "[axes.Q]", "[surface]", "[sensor]", "[channel]", "[variables]",
                    "[[events]]", "[[events.plc]]", "[events]", "[[sensor.faults]]"]


@st.composite
def scenario_text(draw) -> str:
    """An example scenario with values replaced, lines dropped / duplicated and keys / tables added."""
    lines = draw(st.sampled_from(SCENARIOS)).decode("utf-8").splitlines()
    for _ in range(draw(st.integers(1, 6))):
        kind = draw(st.sampled_from(["value", "value", "value", "drop", "dup", "key", "header"]))
        at = draw(st.integers(0, max(0, len(lines) - 1)))
        if kind == "value":
            assignments = [i for i, line in enumerate(lines) if "=" in line and not line.lstrip().startswith("#")]
            if assignments:
                i = draw(st.sampled_from(assignments))
                lines[i] = lines[i].split("=", 1)[0] + "= " + draw(TOML_VALUES)
        elif kind == "drop" and lines:
            del lines[at]
        elif kind == "dup" and lines:
            lines.insert(at, lines[at])
        elif kind == "key":
            lines.insert(at, f"{draw(st.sampled_from(SCENARIO_KEYS))} = {draw(TOML_VALUES)}")
        else:
            lines.insert(at, draw(st.sampled_from(SCENARIO_HEADERS)))
    return "\n".join(lines) + "\n"


def check_scenario(text: str) -> None:
    tally("fuzz_scenario", inputs=1)
    with bounded("scenario_from_text"):
        try:
            scenario = scenario_from_text(text, base_dir=SCN, source="fuzz.toml")
        except ScenarioError as exc:
            scenario = None
            assert exc.file == "fuzz.toml" and str(exc).startswith("fuzz.toml"), str(exc)
            assert exc.key and len(str(exc)) > len("fuzz.toml: "), str(exc)
            if exc.key == "toml":                      # a TOML syntax error: the line is known ...
                assert exc.line is not None and 1 <= exc.line <= n_lines(text) + 1, str(exc)
        except ParameterError as exc:                  # a referenced list file: its own file:line
            scenario = None
            assert exc.file and exc.line is not None and str(exc).strip(), str(exc)
        except NcSyntaxError as exc:                   # the referenced NC program
            scenario = None
            assert exc.file and exc.line is not None and exc.message, str(exc)
    if scenario is None:
        tally("fuzz_scenario", rejected=1)
        return
    tally("fuzz_scenario", accepted=1)
    short = dataclasses.replace(scenario, duration=min(scenario.duration or RUN_SECONDS, RUN_SECONDS),
                                settle_time=0.0)
    with bounded("run"):
        try:
            result = run(short, keep_trace=False)
        except NcSyntaxError as exc:                   # program = a file that does not parse
            tally("fuzz_scenario", run_rejected=1)
            assert exc.file and exc.line is not None and exc.message, str(exc)
            return
    tally("fuzz_scenario", ran=1)
    if result.errors or result.aborted:
        tally("fuzz_scenario", runtime_error=1)


@RELIABILITY
@given(scenario_text())
def test_scenario_generated(text):
    check_scenario(text)


@RELIABILITY
@given(mutated(SCENARIOS))
def test_scenario_mutated(text):
    check_scenario(text)


def test_scenario_examples_themselves_load_and_run():
    for data in SCENARIOS:
        check_scenario(data.decode("utf-8"))


def test_no_stray_distctrl_error_types():
    """The documented error types are all DistCtrlError subclasses (what callers catch)."""
    for exc_type in (NcSyntaxError, ParameterError, ScenarioError):
        assert issubclass(exc_type, DistCtrlError)
    with pytest.raises(ScenarioError):
        scenario_from_text("= broken", base_dir=SCN, source="fuzz.toml")


# ------------------------------------------------------------------ bugs found by the fuzzing (fixed)

# tomllib reports '(at end of document)' instead of 'at line N'; the error now names the last line
@pytest.mark.parametrize("text", ['name = "x', "name", "x = 1\n[a"])
def test_bug_toml_error_at_end_of_document_has_a_line(text):
    with pytest.raises(ScenarioError) as info:
        scenario_from_text(text, base_dir=SCN, source="fuzz.toml")
    assert info.value.line == n_lines(text)
