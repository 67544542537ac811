"""docs/control-law.md shows the figures tools/law_figures.py measures (regenerate: `make docs`)."""
from __future__ import annotations

import pathlib

from tests.scripts import load_script

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _tool():
    return load_script("tools/law_figures.py")


def test_control_law_page_shows_the_measured_figures():
    tool = _tool()
    text = (ROOT / "docs" / "control-law.md").read_text(encoding="utf-8")
    start, end = text.index(tool.BEGIN), text.index(tool.END) + len(tool.END)
    assert text[start:end] == tool.render(), "docs/control-law.md is out of date: run `make docs`"


def test_the_page_quotes_the_documents_claims_beside_the_figures():
    text = (ROOT / "docs" / "control-law.md").read_text(encoding="utf-8")
    for claim in ("P-AXIS-00783", "P-AXIS-00784", "P-AXIS-00765", "P-AXIS-00500", "P-AXIS-00501",
                  "FCT-M3 §4.4.1", "FCT-M3 §7.1", "FCT-M3 §7.2"):
        assert claim in text
