"""The traceability matrix: every checkable item of the documents, the code and the test for it.

The matrix lives in machine-readable tables, ``docs/traceability/*.toml`` (one file per part: the
axis variant, the PLC interface, the channel variant); ``docs/traceability.md`` is generated from
them. ``python tools/traceability.py`` prints the page (``make docs`` writes it),
``python tools/traceability.py --check`` validates the tables and exits 1 listing every problem.
tests/test_traceability.py runs the check and keeps the page current, so an item without a test, a
test that does not exist or code that does not exist fails the suite.

Each table has ``[meta] title`` and ``[[item]]`` entries::

    id      unique over all files (AX-..., HLI-..., CH-...)
    kind    keyword | value-range | parameter | error | state | transition | object | hli |
            example | behaviour | dynamic-claim
    source  the document and section (FCT-M3 §6, PROG #DIST CTRL, HLI DistanceControl,
            TF5200 Abstandskontrolle §7.5); never a path of the document files
    item    what the document says, one line
    code    files (or file::symbol) that implement it
    tests   path::function or path::Class::method (a "[...]" parametrization suffix is ignored)
    status  implemented | not-implemented | not-checkable
    reason  why, for the two others
    note    optional: a decision (SPEC section, docs page)
"""
from __future__ import annotations

import ast
import sys
from dataclasses import dataclass, field
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10
    import tomli as tomllib          # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parents[1]
TABLES = ROOT / "docs" / "traceability"
PAGE = ROOT / "docs" / "traceability.md"
KINDS = ("keyword", "value-range", "parameter", "error", "state", "transition", "object", "hli", "example",
         "behaviour", "dynamic-claim")
STATUSES = ("implemented", "not-implemented", "not-checkable")
FIELDS = {"id", "kind", "source", "item", "code", "tests", "status", "reason", "note"}


@dataclass
class Item:
    file: str
    id: str
    kind: str
    source: str
    item: str
    code: list = field(default_factory=list)
    tests: list = field(default_factory=list)
    status: str = "implemented"
    reason: str = ""
    note: str = ""
    unknown: tuple = ()


@dataclass
class Table:
    file: str
    title: str
    items: list


def load(folder: Path = TABLES) -> list[Table]:
    tables = []
    for path in sorted(folder.glob("*.toml")):
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        title = data.get("meta", {}).get("title", path.stem)
        items = []
        for raw in data.get("item", []):
            known = {k: raw[k] for k in raw if k in FIELDS}
            items.append(Item(file=path.name, **{"id": "", "kind": "", "source": "", "item": "", **known},
                              unknown=tuple(sorted(set(raw) - FIELDS))))
        tables.append(Table(path.name, title, items))
    return tables


# ----------------------------------------------------------------------------- checks

_DEFS: dict[Path, set[str]] = {}


def _definitions(path: Path) -> set[str]:
    """Names defined in a Python file: top-level functions/classes/assignments and Class.method."""
    if path not in _DEFS:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names: set[str] = set()
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.add(node.name)
                if isinstance(node, ast.ClassDef):
                    for sub in node.body:
                        if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)):
                            names.add(f"{node.name}.{sub.name}")
                        elif isinstance(sub, ast.Assign):
                            names.update(f"{node.name}.{t.id}" for t in sub.targets if isinstance(t, ast.Name))
            elif isinstance(node, ast.Assign):
                names.update(t.id for t in node.targets if isinstance(t, ast.Name))
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                names.add(node.target.id)
        _DEFS[path] = names
    return _DEFS[path]


def _check_reference(ref: str, root: Path, what: str) -> str:
    """'' when ``ref`` (path or path::name) exists, else the problem."""
    path_text, _, name = ref.partition("::")
    path = root / path_text
    if not path.is_file():
        return f"{what} file {path_text!r} does not exist"
    if not name:
        return ""
    if path.suffix != ".py":
        return f"{what} {ref!r}: a symbol can only be named in a Python file"
    name = name.split("[", 1)[0].replace("::", ".")
    if name not in _definitions(path):
        return f"{what} {ref!r}: {name!r} is not defined in {path_text}"
    return ""


def check(tables: list[Table], root: Path = ROOT) -> list[str]:
    """Every problem of the tables, one line each, naming the file and the item."""
    problems: list[str] = []
    seen: dict[str, str] = {}
    for table in tables:
        if not table.items:
            problems.append(f"{table.file}: no items")
        for it in table.items:
            where = f"{it.file} {it.id or '(no id)'}"
            if not it.id:
                problems.append(f"{where}: no id")
            elif it.id in seen:
                problems.append(f"{where}: id used twice (also in {seen[it.id]})")
            else:
                seen[it.id] = it.file
            if it.unknown:
                problems.append(f"{where}: unknown fields {', '.join(it.unknown)}")
            if it.kind not in KINDS:
                problems.append(f"{where}: kind {it.kind!r}; allowed: {', '.join(KINDS)}")
            if it.status not in STATUSES:
                problems.append(f"{where}: status {it.status!r}; allowed: {', '.join(STATUSES)}")
            if not str(it.source).strip():
                problems.append(f"{where}: no source (document and section)")
            if "seeds/" in str(it.source) or "seeds/" in str(it.item) or "seeds/" in str(it.note):
                problems.append(f"{where}: cites a document file (seeds/...); cite the document's title and section")
            if not str(it.item).strip():
                problems.append(f"{where}: no item text")
            if it.status == "implemented":
                if not it.tests:
                    problems.append(f"{where}: implemented but no test")
                if not it.code:
                    problems.append(f"{where}: implemented but no code")
            elif not str(it.reason).strip():
                problems.append(f"{where}: {it.status} without a reason")
            for ref in it.tests:
                problem = _check_reference(str(ref), root, "test")
                if problem:
                    problems.append(f"{where}: {problem}")
                elif not str(ref).startswith("tests/"):
                    problems.append(f"{where}: test {ref!r} is not under tests/")
            for ref in it.code:
                problem = _check_reference(str(ref), root, "code")
                if problem:
                    problems.append(f"{where}: {problem}")
    return problems


# ----------------------------------------------------------------------------- the page

def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _short_test(ref: str) -> str:
    path, _, name = ref.partition("::")
    return f"`{Path(path).name}::{name}`" if name else f"`{path}`"


def render(tables: list[Table]) -> str:
    lines = [
        "# Traceability matrix",
        "",
        "Generated from `docs/traceability/*.toml` by `python tools/traceability.py` (`make docs`) — do",
        "not edit by hand. Every checkable item of the documents (FCT-M3 Distance control, PROG #DIST CTRL,",
        "HLI DistanceControl, TF5200 Abstandskontrolle; docs/documents.md lists them) with the",
        "section that states it, the code that implements it and the tests that check it.",
        "`tests/test_traceability.py` fails when an implemented item has no test, or when a listed test",
        "or code file does not exist; items the project does not implement, or that a simulator cannot",
        "check, are listed with the reason.",
        "",
        "## Summary",
        "",
        "| part | items | implemented | not implemented | not checkable |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    total = [0, 0, 0, 0]
    for t in tables:
        counts = [len(t.items)] + [sum(1 for i in t.items if i.status == s) for s in STATUSES]
        total = [a + b for a, b in zip(total, counts)]
        lines.append(f"| {t.title} | " + " | ".join(str(c) for c in counts) + " |")
    lines.append("| **all** | " + " | ".join(f"**{c}**" for c in total) + " |")
    lines += ["", "| kind | items |", "| --- | ---: |"]
    every = [i for t in tables for i in t.items]
    for kind in KINDS:
        n = sum(1 for i in every if i.kind == kind)
        if n:
            lines.append(f"| {kind} | {n} |")
    for t in tables:
        lines += ["", f"## {t.title}", "", f"From `docs/traceability/{t.file}`.", "",
                  "| id | source | item | kind | code | tests | status |",
                  "| --- | --- | --- | --- | --- | --- | --- |"]
        for it in t.items:
            code = "<br>".join(f"`{c}`" for c in it.code) or "—"
            tests = "<br>".join(_short_test(r) for r in it.tests) or "—"
            status = it.status if it.status == "implemented" else f"{it.status}: {_cell(it.reason)}"
            if it.note:
                status += f" ({_cell(it.note)})"
            lines.append(f"| {it.id} | {_cell(it.source)} | {_cell(it.item)} | {it.kind} | {code} | {tests} | "
                         f"{status} |")
    lines.append("")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    tables = load()
    if argv == ["--check"]:
        problems = check(tables)
        for p in problems:
            print(p)
        return 1 if problems else 0
    if argv == ["--write"]:
        PAGE.write_text(render(tables), encoding="utf-8")
        return 0
    if argv:
        print("usage: python tools/traceability.py [--check | --write]", file=sys.stderr)
        return 2
    sys.stdout.write(render(tables))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
