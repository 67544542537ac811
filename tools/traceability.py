"""The traceability matrix: every checkable item of the documents, the code and the test for it.

The matrix lives in machine-readable tables, ``docs/traceability/*.toml`` (one file per part: the
axis variant, the PLC interface, the channel variant); ``docs/traceability.md`` is generated from
them. ``python tools/traceability.py`` prints the page (``make docs`` writes it),
``python tools/traceability.py --check`` validates the tables and exits 1 listing every problem.
tests/test_traceability.py runs the check and keeps the page current, so an item without a test, a
test that does not exist, code that does not exist, or a weak row (a claimed attribute no cited test
mentions, a parameter its tests never name; see "weak rows" below) fails the suite.

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
import re
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


# ----------------------------------------------------------------------------- weak rows
#
# A row's cited tests must be able to back its claim. Two mechanical checks catch the weak rows an
# audit found (a claim "ID, key, type, unit, range and default as documented" whose tests assert
# neither type nor unit; a parameter row whose tests never name the parameter):
#
# * claim list: an item that says "<a>, <b> ... and <z> as documented" claims each attribute; for
#   each one, at least one cited test must mention it (CLAIM_WORDS);
# * subject: a parameter item naming a parameter ID (P-AXIS-nnnnn, P-CHAN-nnnnn) must cite at least one test
#   that mentions the ID, the parameter's list key or its last key component (any case: the NC
#   keyword KP names P-AXIS-00759's kp).
#
# "Mention" is textual: the test function's source with its decorators, plus the source of the
# module-level names the function uses (the tables a parametrized test reads). It cannot tell an
# assertion from a comment, nor see that a value is compared with the field it is computed from;
# the review of a row's wording stays a human's job.

#: attribute of a claim list -> what a test that checks it must contain (a regular expression)
CLAIM_WORDS = {
    "id": r"\bids?\b|param_id|\bpid\b|P-(?:AXIS|CHAN)-\d{5}",
    "key": r"\bkeys?\b|kenngr\.|dist_ctrl\[",
    "type": r"\btype(?:_name)?\b|\bads_type\b|\bdata type",
    "unit": r"\bunits?\b",
    "range": r"range|\ballowed\b",
    "default": r"default",
    "offset": r"offset",
    "length": r"\blength\b|\bsize\b",
    "access": r"access|writable|read_only",
}
_CLAIM_LIST = re.compile(r"((?:\b(?:%s)\b(?:,\s*|\s+and\s+))+\b(?:%s)\b)\s+as documented"
                         % ("|".join(CLAIM_WORDS), "|".join(CLAIM_WORDS)), re.IGNORECASE)
_PARAM_ID = re.compile(r"\bP-(?:AXIS|CHAN)-\d{5}\b")
_SOURCES: dict[tuple[Path, str], str] = {}


def claimed_attributes(item: str) -> list[str]:
    """The attributes an item claims "as documented" (lower case, in the order written)."""
    out: list[str] = []
    for m in _CLAIM_LIST.finditer(item):
        out += [w.lower() for w in re.findall(r"\b(?:%s)\b" % "|".join(CLAIM_WORDS), m.group(1), re.IGNORECASE)]
    return out


def test_source(ref: str, root: Path = ROOT) -> str:
    """The text a cited test mentions things in: the function (or class) with its decorators and the
    module-level assignments it refers to by name. '' when it cannot be found."""
    path_text, _, name = str(ref).partition("::")
    name = name.split("[", 1)[0].replace("::", ".")
    key = (root / path_text, name)
    if key in _SOURCES:
        return _SOURCES[key]
    path = root / path_text
    text = ""
    if path.is_file() and path.suffix == ".py" and name:
        src = path.read_text(encoding="utf-8")
        tree = ast.parse(src)
        lines = src.splitlines()
        top = {n.name: n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))}
        assigns: dict[str, ast.stmt] = {}
        for n in tree.body:
            targets = n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, ast.AnnAssign) else []
            for t in targets:
                if isinstance(t, ast.Name):
                    assigns[t.id] = n
        first, _, rest = name.partition(".")
        node = top.get(first)
        if node is not None and rest and isinstance(node, ast.ClassDef):
            node = next((n for n in node.body if getattr(n, "name", None) == rest), node)
        if node is not None:
            def segment(n) -> str:
                start = min([d.lineno for d in getattr(n, "decorator_list", [])] + [n.lineno])
                return "\n".join(lines[start - 1:n.end_lineno])
            parts = [segment(node)]
            used = {x.id for x in ast.walk(node) if isinstance(x, ast.Name)}
            parts += [segment(assigns[u]) for u in sorted(used) if u in assigns]
            text = "\n".join(parts)
    _SOURCES[key] = text
    return text


def weak_claims(it: Item, root: Path = ROOT) -> list[str]:
    """The problems of an implemented item whose cited tests cannot back its claim (see above)."""
    if it.status != "implemented" or not it.tests:
        return []
    sources = [test_source(str(ref), root) for ref in it.tests]
    problems = []
    missing = [w for w in dict.fromkeys(claimed_attributes(str(it.item)))
               if not any(re.search(CLAIM_WORDS[w], s, re.IGNORECASE) for s in sources)]
    if missing:
        problems.append(f"claims {', '.join(missing)} as documented but no cited test mentions "
                        f"{'it' if len(missing) == 1 else 'them'}")
    for pid in dict.fromkeys(_PARAM_ID.findall(str(it.item)) if it.kind == "parameter" else []):
        names = list(dict.fromkeys([pid] + _parameter_names(pid)))
        if not any(re.search(r"(?<!\w)" + re.escape(n) + r"(?!\w)", s, re.IGNORECASE)
                   for s in sources for n in names):
            problems.append(f"names {pid} but no cited test mentions {' or '.join(names)}")
    return problems


def _parameter_names(pid: str) -> list[str]:
    """The list key of a parameter ID and its last component (from the project's tables), if known."""
    try:
        sys.path.insert(0, str(ROOT))
        from distctrl.params.channel import BY_ID as CHANNEL_BY_ID
        from distctrl.params.table import BY_ID as AXIS_BY_ID
    except Exception:                  # noqa: BLE001 - the check then relies on the ID alone
        return []
    finally:
        if sys.path and sys.path[0] == str(ROOT):
            sys.path.pop(0)
    spec = AXIS_BY_ID.get(pid) or CHANNEL_BY_ID.get(pid)
    if spec is None:
        return []
    return [spec.key, spec.key.rsplit(".", 1)[-1], spec.field]


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
            if not any(where in p and "test" in p for p in problems):
                problems += [f"{where}: {p}" for p in weak_claims(it, root)]
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
        "check, are listed with the reason. It also fails on two kinds of weak rows: an item that claims",
        "attributes \"as documented\" (\"ID, key, type, unit, range and default\", \"offset, type, length,",
        "unit and access\") of which one is mentioned by none of its cited tests, and a parameter item",
        "whose cited tests never name the parameter (its ID, list key or field). Those checks are textual:",
        "whether a test compares a value with an independent one, and whether an item's wording",
        "overstates what its tests show, stays a reviewer's question.",
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
