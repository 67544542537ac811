"""README.md and docs/*.md as a reader meets them (new-user audit R13, R16): every relative link and
image points at a file that exists, no markdown table is cut in two by a paragraph (the rows after the
paragraph render as text), and the README's first screen says what to do next."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
# [text](target) and ![alt](target); the target ends at whitespace or ')' (an optional "title" follows)
_LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_FENCE = re.compile(r"^\s*(```|~~~)")


def _prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) outside fenced code blocks."""
    out, fenced = [], False
    for number, line in enumerate(text.splitlines(), 1):
        if _FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            out.append((number, line))
    return out


def relative_links(text: str) -> list[tuple[int, str]]:
    """(line, target) of every link or image that is not a web address, a mail address or an anchor."""
    links = []
    for number, line in _prose_lines(text):
        line = re.sub(r"`[^`]*`", "", line)                 # code spans are not links
        for target in _LINK.findall(line):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
                continue
            links.append((number, target.split("#", 1)[0]))
    return links


def _is_table_row(line: str) -> bool:
    """A row as this project writes them: starts and ends with '|' (in a list item it may be indented)."""
    stripped = line.strip()
    return len(stripped) > 1 and stripped.startswith("|") and stripped.endswith("|")


_DELIMITER = re.compile(r"^\s*\|(\s*:?-{3,}:?\s*\|)+\s*$")


def interrupted_tables(text: str) -> list[int]:
    """Line numbers of table rows that render as text: a run of rows whose second line is not the
    delimiter row (| --- |), as when a paragraph cuts a table and its last rows follow the paragraph
    (a table needs its header and delimiter row again)."""
    bad, block = [], []
    for number, line in [*_prose_lines(text), (0, "")]:
        if _is_table_row(line):
            block.append((number, line))
            continue
        if block and (len(block) < 2 or not _DELIMITER.match(block[1][1])):
            bad.extend(n for n, _ in block)
        block = []
    return bad


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_and_image_exists(page):
    missing = [f"{page.relative_to(ROOT)}:{line}: {target}" for line, target in
               relative_links(page.read_text(encoding="utf-8")) if target and not (page.parent / target).exists()]
    assert not missing, "broken links:\n" + "\n".join(missing)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_table_is_cut_by_a_paragraph(page):
    rows = interrupted_tables(page.read_text(encoding="utf-8"))
    assert not rows, f"{page.relative_to(ROOT)}: table rows after a paragraph (render as text) at lines {rows}"


def test_the_checks_find_what_they_look_for():
    """The two checks on made-up pages: a broken image, a web link, a code span, a cut table."""
    page = "![a](img/none.png) [b](https://example.org/x) `[c](nowhere.md)` [d](run.md#metrics)\n"
    assert relative_links(page) == [(1, "img/none.png"), (1, "run.md")]
    cut = "| a | b |\n| --- | --- |\n| 1 | 2 |\n**Note.** text\n| 3 | 4 |\n"
    assert interrupted_tables(cut) == [5]
    two = "| a | b |\n| --- | --- |\n| 1 | 2 |\n\ntext\n\n| c | d |\n| --- | --- |\n"
    assert interrupted_tables(two) == []
    fenced = "| a |\n| --- |\ntext\n```\n| not a table |\n```\n"
    assert interrupted_tables(fenced) == []


def test_the_readme_first_screen_says_what_to_do_next():
    """new-user audit R16: the README's first screen (40 lines) keeps the two commands at the top and
    tells a newcomer what to do next, with links; the install is from a clone, not a package index."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert lines[2] == "```sh" and lines[3].startswith("make demo    #") and lines[4].startswith("make test    #")
    first = "\n".join(lines[:40])
    assert "## Start here" in first and "out/demo/sheet_report/index.html" in first
    assert first.count("](docs/") >= 4
    text = "\n".join(lines)
    assert "pip install ." in text and "pip install '.[sim]'" in text and "pip install distctrl" not in text
    assert "0.1 µm" in text and "P-AXIS-00422" in text                  # sensor_increments in mm


def repeated_headings(text: str) -> list[int]:
    """Line numbers of a heading that repeats the heading just before it (nothing but blank lines
    between), as a merge can leave it: the reader sees the same title twice."""
    bad, last = [], None
    for number, line in _prose_lines(text):
        if not line.strip():
            continue
        if line.startswith("#") and last is not None and line.strip() == last:
            bad.append(number)
        last = line.strip() if line.startswith("#") else None
    return bad


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_heading_is_repeated(page):
    assert repeated_headings(page.read_text(encoding="utf-8")) == []
    assert repeated_headings("## A\n## A\n") == [2] and repeated_headings("## A\ntext\n## A\n") == []
