"""The traceability matrix (docs/traceability.md from docs/traceability/*.toml) stays complete: every
implemented item has a test that exists and code that exists, the other items say why, and the page
is the one the tables generate (tools/traceability.py)."""
from __future__ import annotations

from pathlib import Path

import pytest

from tests.scripts import load_script

ROOT = Path(__file__).resolve().parents[1]


def _tool():
    return load_script("tools/traceability.py", registered=True)   # (dataclasses look their module up)


tr = _tool()


def test_the_tables_have_no_problem():
    problems = tr.check(tr.load())
    assert problems == [], "\n".join(problems)


def test_every_part_of_the_documents_has_a_table():
    files = {t.file for t in tr.load()}
    assert files == {"axis.toml", "hli.toml", "channel.toml"}
    counts = {t.file: len(t.items) for t in tr.load()}
    assert counts["axis.toml"] >= 180 and counts["channel.toml"] >= 140 and counts["hli.toml"] >= 40


def test_the_page_is_generated_from_the_tables():
    page = (ROOT / "docs" / "traceability.md").read_text(encoding="utf-8")
    assert page == tr.render(tr.load()), "run `make docs` (python tools/traceability.py --write)"


def test_every_kind_the_issue_names_is_covered():
    kinds = {it.kind for t in tr.load() for it in t.items}
    assert {"keyword", "value-range", "parameter", "error", "state", "transition", "object", "hli", "example",
            "dynamic-claim"} <= kinds


# ----------------------------------------------------------------------------- the checker itself

def _table(tmp_path: Path, body: str, name: str = "t.toml") -> list:
    folder = tmp_path / "tables"
    folder.mkdir(exist_ok=True)
    (folder / name).write_text('[meta]\ntitle = "T"\n\n' + body, encoding="utf-8")
    return tr.load(folder)


def _item(**fields) -> str:
    base = dict(id="X-1", kind="keyword", source="FCT-M3 §6", item="something", code=["tools/traceability.py"],
                tests=["tests/test_traceability.py::test_the_tables_have_no_problem"], status="implemented")
    base.update(fields)
    lines = ["[[item]]"]
    for k, v in base.items():
        if v is None:
            continue
        if isinstance(v, list):
            lines.append(f"{k} = [" + ", ".join(f'"{x}"' for x in v) + "]")
        else:
            lines.append(f'{k} = "{v}"')
    return "\n".join(lines) + "\n\n"


def test_a_good_item_has_no_problem(tmp_path):
    assert tr.check(_table(tmp_path, _item()), ROOT) == []


@pytest.mark.parametrize("fields, words", [
    (dict(tests=["tests/test_traceability.py::test_that_does_not_exist"]), "'test_that_does_not_exist' is not defined"),
    (dict(tests=["tests/no_such_file.py::test_x"]), "test file 'tests/no_such_file.py' does not exist"),
    (dict(tests=["tools/traceability.py::check"]), "is not under tests/"),
    (dict(code=["distctrl/no_such_module.py"]), "code file 'distctrl/no_such_module.py' does not exist"),
    (dict(tests=[]), "implemented but no test"),
    (dict(code=[]), "implemented but no code"),
    (dict(status="not-implemented"), "not-implemented without a reason"),
    (dict(status="done"), "status 'done'"),
    (dict(kind="feature"), "kind 'feature'"),
    (dict(source="seeds/000 §6"), "cites a document file"),
    (dict(source=""), "no source"),
    (dict(id=""), "no id"),
])
def test_the_checker_finds_each_problem(tmp_path, fields, words):
    problems = tr.check(_table(tmp_path, _item(**fields)), ROOT)
    assert any(words in p for p in problems), problems


def test_parametrized_and_class_tests_are_found(tmp_path):
    body = _item(tests=["tests/test_traceability.py::test_the_checker_finds_each_problem[x]",
                        "tests/control/test_state_table.py::DistCtrlMachine"])
    assert tr.check(_table(tmp_path, body), ROOT) == []


def test_an_id_used_twice_and_unknown_fields_are_problems(tmp_path):
    problems = tr.check(_table(tmp_path, _item() + _item() + '[[item]]\nid = "X-2"\ncolour = "red"\n'), ROOT)
    assert any("id used twice" in p for p in problems)
    assert any("unknown fields colour" in p for p in problems)


def test_a_not_implemented_item_with_a_reason_needs_no_test(tmp_path):
    body = _item(status="not-implemented", reason="no licences in a simulator", tests=[], code=[])
    assert tr.check(_table(tmp_path, body), ROOT) == []
    page = tr.render(_table(tmp_path, body))
    assert "not-implemented: no licences in a simulator" in page and "| **all** | **1** | **0** | **1** | **0** |" in page


# ----------------------------------------------------------------------------- weak rows (audit 2026-11-27)
# A row whose cited tests cannot back its claim: the audit's WEAK kinds that a machine can see.

B27_BEFORE = ["tests/params/test_listfile.py::test_every_documented_key_is_in_the_table",
              "tests/params/test_listfile.py::test_out_of_range_values_name_id_value_and_range",
              "tests/params/test_listfile.py::test_defaults_are_the_documented_ones",
              "tests/params/test_listfile.py::test_the_remaining_defaults_are_the_documented_ones"]
B27_ITEM = ("P-AXIS-00764 kenngr.distc.i_tn: integral action time [s] (0..50, 0 = no I part); ID, key, type, "
            "unit, range and default as documented")


def test_the_claimed_attributes_are_read_from_the_item():
    assert tr.claimed_attributes(B27_ITEM) == ["id", "key", "type", "unit", "range", "default"]
    assert tr.claimed_attributes("DIST_CTRL::kp: offset, type, length, unit and access as documented") == \
        ["offset", "type", "length", "unit", "access"]
    assert tr.claimed_attributes("the filter type as in P-CHAN-00825") == []      # no claim list


def test_a_claim_no_cited_test_mentions_is_a_problem(tmp_path):
    """AX-B27 as the audit found it: its tests assert ID, key, range and default but not type and unit."""
    problems = tr.check(_table(tmp_path, _item(kind="parameter", item=B27_ITEM, tests=B27_BEFORE)), ROOT)
    assert problems == ["t.toml X-1: claims type, unit as documented but no cited test mentions them"]
    fixed = B27_BEFORE + ["tests/params/test_listfile.py::test_key_type_unit_range_and_default_are_the_documented_ones"]
    assert tr.check(_table(tmp_path, _item(kind="parameter", item=B27_ITEM, tests=fixed)), ROOT) == []


def test_a_parameter_row_whose_tests_never_name_the_parameter_is_a_problem(tmp_path):
    body = _item(kind="parameter", item="P-AXIS-00784 smoothing_factor: the weight of the newest value",
                 tests=["tests/params/test_listfile.py::test_cross_parameter_check_names_the_parameters"])
    problems = tr.check(_table(tmp_path, body), ROOT)
    assert len(problems) == 1 and "names P-AXIS-00784 but no cited test mentions" in problems[0]
    assert "kenngr.distc.smoothing_factor" in problems[0]
    good = _item(kind="parameter", item="P-AXIS-00784 smoothing_factor: the weight of the newest value",
                 tests=["tests/params/test_listfile.py::test_defaults_are_the_documented_ones"])
    assert tr.check(_table(tmp_path, good), ROOT) == []
    # a keyword row that names the parameter only for its range is about the keyword, not checked so
    keyword = _item(kind="keyword", item="SMOOTH_FACT per P-AXIS-00784",
                    tests=["tests/params/test_listfile.py::test_cross_parameter_check_names_the_parameters"])
    assert tr.check(_table(tmp_path, keyword), ROOT) == []


def test_a_test_mentions_what_its_module_level_tables_hold():
    """A parametrized test reads its table from the module: the table counts as the test's text."""
    text = tr.test_source("tests/params/test_listfile.py::test_key_type_unit_range_and_default_are_the_documented_ones")
    assert "def test_key_type_unit_range_and_default_are_the_documented_ones" in text
    assert '"P-AXIS-00764": ("kenngr.distc.i_tn", "REAL64", "s"' in text          # DOCUMENTED
    assert "RESOLVED_RANGES" in text and "@pytest.mark.parametrize" in text
    assert tr.test_source("tests/params/test_listfile.py::no_such_test") == ""
