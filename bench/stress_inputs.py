"""Fast generators of hostile text inputs for the resumable campaigns (bench/stress.py, issue 30).

The same families as the hypothesis strategies of tests/reliability/test_input_fuzz.py (grammar-aware
NC programs of both dialects, parameter lists of axis and channel, scenario TOML edited line by line,
byte mutations of every shipped example), drawn from a plain ``random.Random``: hypothesis spends
milliseconds per example on its own bookkeeping, which a 10^6-input campaign cannot afford, and input
``i`` of a campaign is a pure function of (seed, suite, i), so a stopped campaign resumes at ``i``
and any input it reports can be made again (``python bench/stress.py show SUITE I``).
"""
from __future__ import annotations

import random
from pathlib import Path

from distctrl.params import AXIS_PARAMETERS
from distctrl.params.channel import CHANNEL_PARAMETERS

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SCN = EXAMPLES / "scenarios"

NC_EXAMPLES = [p.read_bytes() for p in sorted(EXAMPLES.glob("*.nc")) + sorted(SCN.glob("*.nc"))]
AXIS_LISTS = [p.read_bytes() for p in [EXAMPLES / "axis_z_9_3.lis", SCN / "z_probe.lis", SCN / "z_laser.lis"]]
CHANNEL_LISTS = [p.read_bytes() for p in [EXAMPLES / "channel_3d_12_8_3.lis", SCN / "channel_3d.lis"]]
SCENARIOS = [p.read_bytes() for p in sorted(SCN.glob("*.toml"))]


def rbytes(r: random.Random, lo: int, hi: int) -> bytes:
    return bytes(r.getrandbits(8) for _ in range(r.randint(lo, hi)))


def mutated(r: random.Random, originals: list[bytes]) -> str:
    """An example file with 1..8 byte edits (insert, delete, replace, duplicate, bit flip)."""
    data = bytearray(r.choice(originals))
    for _ in range(r.randint(1, 8)):
        kind = r.choice(("insert", "delete", "replace", "duplicate", "flip"))
        at = r.randint(0, len(data))
        if kind == "insert":
            data[at:at] = rbytes(r, 1, 6)
        elif kind == "delete":
            del data[at:at + r.randint(1, 12)]
        elif kind == "replace":
            chunk = rbytes(r, 1, 4)
            data[at:at + len(chunk)] = chunk
        elif kind == "duplicate":
            data[at:at] = data[at:at + r.randint(1, 40)] * r.randint(1, 3)
        elif at < len(data):
            data[at] ^= 1 << r.randint(0, 7)
    return bytes(data).decode("utf-8", errors="replace")


# ------------------------------------------------------------------ NC programs

SPECIAL_NUMBERS = ["0", "0.0", "-0", "1e9", "1e-9", "1e308", "-1e308", "1e999", ".5", "5.", "-.1", "30", "10", "1",
                   "0.001", "1E3", "nan", "inf", "-", "1..2", "0x1F", "9" * 40]
VARIABLES = ["V.E.SENSOR", "V.E.HEIGHT", "V.E.UNDEFINED", "V.G.WZ_AKT.L", "V.E.X"]
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
GARBAGE_KW = ["FOO", "ON=1", "=", "SET_POS=", "KP==1", "[", "]", "DIST_CTRL", "#", ";x", "(", ")", "\t", "\x00",
              "ÿ", "SET_DIST=[", "KP=1e999", "N_CYCLES=1e12", "ORDER=-1"]


def number(r: random.Random) -> str:
    k = r.randint(0, 3)
    if k == 0:
        return str(r.randint(-10**6, 10**6))
    if k == 1:
        return f"{r.uniform(-1e4, 1e4):g}" if r.random() < 0.8 else f"{r.uniform(-1, 1) * 10 ** r.randint(-40, 40):g}"
    return r.choice(SPECIAL_NUMBERS)


def expression(r: random.Random, depth: int = 0) -> str:
    if depth > 2 or r.random() < 0.5:
        return number(r) if r.random() < 0.7 else r.choice(VARIABLES)
    op = r.choice("+-*/") if r.random() < 0.9 else "**"
    a, b = expression(r, depth + 1), expression(r, depth + 1)
    return r.choice((f"{a}{op}{b}", f"[{a}{op}{b}]", f"-{a}"))


def value(r: random.Random) -> str:
    return number(r) if r.random() < 0.67 else expression(r)


def keyword_args(r: random.Random, flags, number_kw, name_kw) -> list[str]:
    args = []
    for _ in range(r.randint(0, 5)):
        kind = r.choice(("flag", "number", "name", "garbage")) if r.randint(0, 9) else "garbage"
        if kind == "flag":
            args.append(r.choice(flags))
        elif kind == "number":
            args.append(f"{r.choice(number_kw)}={value(r)}")
        elif kind == "name":
            kw = r.choice(name_kw)
            args.append(f"{kw}={r.choice(NAME_VALUES[kw])}")
        else:
            args.append(r.choice(GARBAGE_KW))
    return args


def nc_block(r: random.Random, three_d: bool) -> str:
    kinds = 7 + (4 if three_d else 0)
    k = r.randrange(kinds)
    if k == 0:
        args = keyword_args(r, AXIS_FLAGS, AXIS_NUMBER_KW, ["SENSOR_SOURCE", "SENSOR_VAR", "FILTER_TYPE"])
        body = f"{r.choice('ZZXYA')}[DIST_CTRL {' '.join(args)}]"
    elif k == 1:
        words = [r.choice(("G0", "G1", "G90", "G91")) for _ in range(r.randint(0, 2))]
        for axis in r.sample("XYZAC", r.randint(0, 3)):
            words.append(f"{axis}{number(r)}" if r.random() < 0.5 else f"{axis}={value(r)}")
        if r.random() < 0.5:
            words.append(f"F{r.choice(['3000', '6000', '0', '-1', '1e9', '1e-9'])}")
        body = " ".join(words)
    elif k == 2:
        body = "M30"
    elif k == 3:
        body = f"#TIME {number(r)}"
    elif k == 4:
        body = f"V.E.{r.choice(['SENSOR', 'HEIGHT', 'X'])} = {value(r)}"
    elif k == 5:
        body = ";comment"
    elif k == 6:
        body = "(paren comment)"
    elif k in (7, 8):
        outside = [r.choice(["WAIT", "ON", "OFF", "FREEZE", "DRYRUN", "CHECK_POS", "REF"]) for _ in range(r.randint(0, 2))]
        args = keyword_args(r, FLAGS_3D, NUMBER_KW_3D, list(NAME_VALUES))
        bracket = f" [{' '.join(args)}]" if args or r.random() < 0.5 else ""
        body = f"#DIST CTRL {' '.join(outside)}{bracket}".replace("  ", " ")
    elif k == 9:
        body = f"V.G.KIN_STEP[1].ID[98].PARAM[{r.randint(-1, 5)}] = {number(r)}"
    else:
        body = r.choice(["#KIN ID[9.98]", "#TRAFO ON", "#TRAFO OFF", "V.G.WZ_AKT.L = 80"])
    num = f"N{r.randint(0, 99999)} " if r.randint(0, 4) else ""
    return num + body + r.choice(("", "", " ;note", " (c)"))


def nc_program(r: random.Random) -> str:
    three_d = r.random() < 0.5
    blocks = [nc_block(r, three_d) for _ in range(r.randint(1, 8))]
    if r.random() < 0.5:
        blocks.insert(0, "%FUZZ")
    if r.randint(0, 3):
        blocks.append("N999 M30")
    return r.choice(("\n", "\r\n")).join(blocks) + r.choice(("", "\n"))


def nc_input(r: random.Random) -> str:
    """Half generated programs, half mutated examples."""
    return nc_program(r) if r.random() < 0.5 else mutated(r, NC_EXAMPLES)


# ------------------------------------------------------------------ parameter lists

AXIS_KEYS = sorted({k for s in AXIS_PARAMETERS for k in (s.key, *s.aliases)})
CHANNEL_KEYS = sorted({k for s in CHANNEL_PARAMETERS for k in (s.key, *s.aliases)})
LIST_SPECIAL = ["0", "1", "2", "-1", "0.5", "1e3", "1e400", "nan", "inf", "-inf", "0x10", "1_000", "KALMAN_MA",
                "KALMAN", "MA", "PT1", "LOW_PASS", "NONE", "TRUE", "", "1 2", "#1", "1e-400", "-0", "+5", "٣"]


def list_value(r: random.Random) -> str:
    k = r.randint(0, 3)
    if k == 0:
        return str(r.randint(-2**40, 2**40))
    if k == 1:
        return str(r.randint(-3, 100))
    if k == 2:
        return repr(r.choice((r.uniform(-1e6, 1e6), r.uniform(-1, 1) * 10.0 ** r.randint(-300, 300),
                              float("nan"), float("inf"))))
    return r.choice(LIST_SPECIAL)


def rtext(r: random.Random, n: int) -> str:
    alphabet = "abcXYZ019 _.-#[]=\t\"'µ°\x00\x7f\u2028é"
    return "".join(r.choice(alphabet) for _ in range(r.randint(0, n)))


def list_text(r: random.Random, keys: list[str]) -> str:
    lines = []
    for _ in range(r.randint(0, 10)):
        kind = r.randint(0, 19)
        if kind == 0:
            lines.append(rtext(r, 30))
        elif kind == 1:
            lines.append("# " + rtext(r, 20))
        elif kind == 2:
            lines.append(r.choice(keys).replace("[0]", f"[{r.randint(0, 3)}]") + " " + list_value(r))
        elif kind == 3:
            lines.append(r.choice(keys))
        else:
            pad = " " * r.randint(1, 20)
            comment = r.choice(("", "", "  # comment", "# x", "\t# [0.1µm] unit"))
            lines.append(f"{r.choice(keys)}{pad}{list_value(r)}{comment}")
    return r.choice(("\n", "\r\n")).join(lines)


def params_input(r: random.Random) -> tuple[str, bool]:
    """(text, channel list?): generated or mutated, axis or channel."""
    channel = r.random() < 0.5
    if r.random() < 0.5:
        return list_text(r, CHANNEL_KEYS if channel else AXIS_KEYS), channel
    return mutated(r, CHANNEL_LISTS if channel else AXIS_LISTS), channel


# ------------------------------------------------------------------ scenarios

TOML_SPECIAL = ['"Z"', '"X"', '"Q"', '""', '"encoder"', '"distance"', '"step"', '"sine"', "true", "false", "[]", "{}",
                "[1, 2]", '"z_probe.lis"', '"../dist_1.nc"', '"missing.nc"', '"../dist3d_1.nc"', '"none"', '"CA"',
                "0", "1e-5", "0.1", "1e300", '"ON"', '"OFF"', '"REF"', "-1", "nan", "inf", "-inf", "1e-300",
                "9223372036854775807", '"/etc/passwd"', '"../../../../etc/hostname"', "[[1]]", "{a = 1}"]
SCENARIO_KEYS = ["name", "cycle_time", "duration", "settle_time", "seed", "tool_length", "start", "kv", "v_max", "a_max",
                 "feedforward", "axis", "kind", "range_min", "range_max", "noise_std", "base", "mode", "variable",
                 "bus_delay_cycles", "resolution", "params", "program", "program_text", "t", "unknown_key"]
SCENARIO_HEADERS = ["[axes.X]", "[axes.Z]", "[axes.Q]", "[surface]", "[sensor]", "[channel]", "[variables]",
                    "[[events]]", "[[events.plc]]", "[events]", "[[sensor.faults]]"]


def toml_value(r: random.Random) -> str:
    k = r.randint(0, 3)
    if k == 0:
        return str(r.randint(-10**6, 10**6))
    if k == 1:
        return repr(r.uniform(-1, 1) * 10.0 ** r.randint(-12, 12))
    if k == 2:
        return '"' + rtext(r, 8).replace("\\", "\\\\").replace('"', '\\"').replace("\x00", "").replace(
            "\x7f", "").replace("\t", " ").replace("\u2028", " ") + '"'
    return r.choice(TOML_SPECIAL)


def scenario_text(r: random.Random) -> str:
    lines = r.choice(SCENARIOS).decode("utf-8").splitlines()
    for _ in range(r.randint(1, 6)):
        kind = r.choice(("value", "value", "value", "drop", "dup", "key", "header"))
        at = r.randint(0, max(0, len(lines) - 1))
        if kind == "value":
            assignments = [i for i, line in enumerate(lines) if "=" in line and not line.lstrip().startswith("#")]
            if assignments:
                i = r.choice(assignments)
                lines[i] = lines[i].split("=", 1)[0] + "= " + toml_value(r)
        elif kind == "drop" and lines:
            del lines[at]
        elif kind == "dup" and lines:
            lines.insert(at, lines[at])
        elif kind == "key":
            lines.insert(at, f"{r.choice(SCENARIO_KEYS)} = {toml_value(r)}")
        else:
            lines.insert(at, r.choice(SCENARIO_HEADERS))
    return "\n".join(lines) + "\n"


def scenario_input(r: random.Random) -> str:
    return scenario_text(r) if r.random() < 0.6 else mutated(r, SCENARIOS)
