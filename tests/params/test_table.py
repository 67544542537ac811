"""The parameter table is the only range table: its NC words, short keys and the P-CHAN twins."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from distctrl.control.commands import Command
from distctrl.control.commands3d import Command3D
from distctrl.control.filters import FILTER_PARAMS, FilterConfig
from distctrl.nc import VALUE_RANGES
from distctrl.params.channel import CHANNEL_PARAMETERS
from distctrl.params.table import AXIS_PARAMETERS, BY_FIELD, BY_NC_WORD
from distctrl.tuning import space
from distctrl.workbench import filters as wb

ROOT = Path(__file__).resolve().parents[2]
GRAMMAR = (ROOT / "distctrl" / "nc" / "grammar.lark").read_text(encoding="utf-8")

#: P-CHAN twins whose range the documents state differently from the axis parameter (FCT-M3 §12.8.2 vs §9.2)
TWIN_RANGE_DIFFERS = {"P-CHAN-00812": "a_min: '1 ... MAX(UNS32)' (channel) against '1 <= a_min < MAX(UNS32)' (axis)"}


def _grammar_words(terminal: str) -> set[str]:
    m = re.search(rf"^{terminal}: /\((.*?)\)\(\?!", GRAMMAR, re.M)
    assert m, terminal
    return set(m.group(1).split("|"))


def test_every_nc_word_of_the_table_is_in_the_nc_grammar():
    numbers, names = _grammar_words("DC_NUMBER_KEY"), _grammar_words("DC_NAME_KEY")
    for word, spec in BY_NC_WORD.items():
        assert word in (names if spec.choices else numbers), (spec.id, word)


def test_every_numeric_nc_word_takes_its_range_from_the_table():
    for word, spec in BY_NC_WORD.items():
        if spec.choices:
            continue
        r = VALUE_RANGES[word]
        assert r.integer == spec.integer
        for value in (spec.lo, spec.hi):
            if value is None:
                continue
            for probe in (value - 1, value, value + 1, value - 0.5, value + 0.5):
                if abs(probe) < 2**31:
                    assert r.contains(probe) == (spec.check(probe) and (not spec.integer or probe == int(probe))), \
                        (word, probe)


def test_the_commands_have_a_field_per_nc_word():
    for word in BY_NC_WORD:
        assert hasattr(Command(), word.lower()), word
        assert word.lower() in Command3D.__dataclass_fields__, word


def test_the_tuning_names_and_words_come_from_the_table():
    assert set(space.NC_WORDS) == {s.field for s in BY_NC_WORD.values()}
    assert all(space.NC_WORDS[f] == BY_FIELD[f].nc_word for f in space.NC_WORDS)
    assert space.ALIASES == {k: s.field for s in AXIS_PARAMETERS for k in (*s.short_keys, s.field) if s.short_keys}


def test_the_filter_parameters_are_filter_config_fields_with_the_table_ranges():
    fields = set(FilterConfig.__dataclass_fields__) - {"filter_type"}
    assert set(FILTER_PARAMS) == fields
    for name, p in FILTER_PARAMS.items():
        assert p.name == name == p.spec.short_keys[0]
        assert wb.KEY_ALIASES[p.field] == name
        assert p.spec.id in wb._RANGES[name]


@pytest.mark.parametrize("chan", [s for s in CHANNEL_PARAMETERS if s.field in BY_FIELD], ids=lambda s: s.id)
def test_p_chan_twins_have_the_axis_range(chan):
    axis = BY_FIELD[chan.field]
    same = (axis.type, axis.lo, axis.hi, axis.lo_open, axis.hi_open, axis.choices) == \
        (chan.type, chan.lo, chan.hi, chan.lo_open, chan.hi_open, chan.choices)
    assert same != (chan.id in TWIN_RANGE_DIFFERS), (chan.id, axis.id)
