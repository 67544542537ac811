"""parse_program never raises anything but NcSyntaxError, and stays fast, on any text."""
from __future__ import annotations

import time
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from distctrl.nc import NcSyntaxError, Program, parse_program

EXAMPLE_DIR = Path(__file__).resolve().parents[2] / "examples"
EXAMPLES = [path.read_text() for path in sorted(EXAMPLE_DIR.glob("dist*.nc"))]
#: characters that matter to the grammar, so mutations reach deep into it
NC_ALPHABET = "NGXYZABCFM#TIME%[]()=+-*/.;\\\n 0123456789eE_VDISTCRLONFK"
#: generous bound (inputs take milliseconds): catches runaway behaviour, not a busy CI machine. It is
#: this process's CPU time, not the wall time, which other processes on a busy machine stretch at will
MAX_SECONDS_PER_INPUT = 2.0
FUZZ = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])


parse_program("")   # build the parser once, outside the timed calls


def check(text: str) -> None:
    started = time.process_time()
    try:
        result = parse_program(text, "fuzz.nc")
    except NcSyntaxError as exc:
        assert not exc.message.startswith("internal parser error"), exc.message
        assert exc.file == "fuzz.nc" and exc.message
        if exc.line is not None:
            assert 1 <= exc.line <= text.count("\n") + text.count("\r") + 2
            assert exc.column is not None and exc.column >= 1
    else:
        assert isinstance(result, Program)
    assert time.process_time() - started < MAX_SECONDS_PER_INPUT


@st.composite
def mutated_example(draw) -> str:
    text = draw(st.sampled_from(EXAMPLES))
    for _ in range(draw(st.integers(1, 6))):
        kind = draw(st.sampled_from(["delete", "insert", "duplicate"]))
        at = draw(st.integers(0, len(text)))
        if kind == "delete":
            text = text[:at] + text[at + draw(st.integers(1, 8)):]
        elif kind == "insert":
            text = text[:at] + draw(st.text(alphabet=st.sampled_from(NC_ALPHABET) | st.characters(),
                                             min_size=1, max_size=4)) + text[at:]
        else:
            piece = text[at:at + draw(st.integers(1, 20))]
            text = text[:at] + piece * draw(st.integers(2, 3)) + text[at:]
    return text


@FUZZ
@given(st.text())
def test_arbitrary_text(text):
    check(text)


@FUZZ
@given(st.text(alphabet=NC_ALPHABET, max_size=200))
def test_text_from_nc_characters(text):
    check(text)


@FUZZ
@given(mutated_example())
def test_mutated_examples(text):
    check(text)


@FUZZ
@given(st.binary(max_size=300))
def test_garbage_bytes_decoded_as_text(data):
    check(data.decode("latin-1"))
    check(data.decode("utf-8", errors="replace"))


def test_examples_themselves_parse():
    for text in EXAMPLES:
        assert isinstance(parse_program(text), Program)
