"""The layer structure of distctrl/ (docs/architecture.md): no import cycle between files, none between
packages, and the lower floors (base, errors, params, control) import only downwards.

The import graph is read with ``ast`` from the source, so it sees what a reader sees: every import
statement counts, at module level, inside functions and methods, and under ``if TYPE_CHECKING:``.
A ``from . import x`` counts as an import of the package's ``__init__`` as well as of ``x`` (a
package face that re-exports a module importing it that way is a circle for a reader).
"""
from __future__ import annotations

import ast
import sys
from pathlib import Path

from tests.scripts import load_script

ROOT = Path(__file__).resolve().parents[1] / "distctrl"

#: packages that must stay out of every package-level cycle (the vocabulary and the cycle core)
LOWER_FLOORS = ("base", "errors", "params", "control")


def modules(root: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every .py below ``root`` (a package's ``__init__`` is the package)."""
    out = {}
    for p in root.rglob("*.py"):
        parts = (root.name, *p.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _resolve(name: str, files: dict[str, Path], top: str) -> str | None:
    while name and name not in files:
        name = name.rpartition(".")[0]
    return name if name and (name == top or name.startswith(top + ".")) else None


def import_graph(root: Path) -> dict[str, set[str]]:
    """module -> the modules of the same tree it imports (anywhere in the file)."""
    files = modules(root)
    top = root.name
    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        pkg = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = pkg.split(".")
                    parts = parts[: len(parts) - (node.level - 1)]
                    base = ".".join(parts + ([base] if base else []))
                names = [f"{base}.{a.name}" for a in node.names] + [base]
            else:
                continue
            targets |= {t for t in (_resolve(n, files, top) for n in names) if t}
        graph[mod] = targets - {mod}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected sets of more than one node (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
    return found


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph between sub-packages (and top-level modules) of the tree: distctrl.x.y -> x."""
    def pkg(m: str) -> str:
        parts = m.split(".")
        return parts[1] if len(parts) > 1 else parts[0]
    out: dict[str, set[str]] = {}
    for a, bs in graph.items():
        for b in bs:
            if pkg(a) != pkg(b):
                out.setdefault(pkg(a), set()).add(pkg(b))
    return out


GRAPH = import_graph(ROOT)


def test_no_file_level_import_cycle():
    assert cycles(GRAPH) == []


def test_no_package_level_import_cycle():
    """No two packages of distctrl import each other, directly or around a circle (every import counts)."""
    assert cycles(package_graph(GRAPH)) == []


def test_base_imports_nothing_of_distctrl():
    """distctrl.base is the ground floor: the vocabulary every other package may use."""
    assert any(m.startswith("distctrl.base") for m in GRAPH)
    assert {m: t for m, t in GRAPH.items() if m.startswith("distctrl.base") and
            any(not x.startswith("distctrl.base") for x in t)} == {}


def test_the_lower_floors_import_only_downwards():
    """base < errors < params < control: none of them imports a package above it."""
    order = {name: i for i, name in enumerate(LOWER_FLOORS)}
    pkgs = package_graph(GRAPH)
    up = {(a, b) for a in LOWER_FLOORS for b in pkgs.get(a, ()) if order.get(b, len(order)) > order[a]}
    assert up == set()


def test_ads_and_the_live_page_attach_to_the_served_machine_as_equals():
    """ADS and the page (ui) do not import each other; the serving layer imports neither."""
    pkgs = package_graph(GRAPH)
    assert "ads" not in pkgs.get("ui", set()) and "ui" not in pkgs.get("ads", set())
    assert pkgs.get("serve", set()) & {"ads", "ui", "cli"} == set()


def test_every_command_is_a_module_of_cli():
    """Only distctrl/cli/ uses click; no package below it imports cli."""
    users = {m for m, path in modules(ROOT).items()
             if "import click" in path.read_text(encoding="utf-8") and not m.startswith("distctrl.cli")}
    assert users == set()
    assert {a for a, bs in package_graph(GRAPH).items() if "cli" in bs} <= {"__main__"}


def test_the_layer_map_of_the_docs_is_the_code_s():
    """docs/architecture.md's floors table is what tools/layer_map.py prints from the source (`make docs`)."""
    layer_map = load_script("tools/layer_map.py")
    doc = (ROOT.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    begin = "<!-- layer_map: begin (generated by tools/layer_map.py, `make docs`) -->\n"
    shown = doc[doc.index(begin) + len(begin):doc.index("<!-- layer_map: end -->")]
    assert shown == layer_map.table(layer_map.package_graph(ROOT))
    assert (ROOT.parent / "docs" / "architecture-layers.svg").is_file()


# the detector itself: a cycle hidden in a function-local import, or under TYPE_CHECKING, is found

def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    root = tmp_path / "pkg"
    for name, text in {"__init__.py": "", **files}.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text, encoding="utf-8")
    return root


def test_a_cycle_through_a_function_local_import_is_found(tmp_path):
    root = _tree(tmp_path, {"a.py": "from .b import x\n", "b.py": "x = 1\ndef f():\n    from .a import y\n"})
    assert cycles(import_graph(root)) == [["pkg.a", "pkg.b"]]


def test_a_cycle_under_type_checking_and_through_a_package_face_is_found(tmp_path):
    root = _tree(tmp_path, {
        "low/__init__.py": "from .one import One\n",
        "low/one.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..high.two import Two\n",
        "high/__init__.py": "",
        "high/two.py": "from .. import low\n",
    })
    graph = import_graph(root)
    assert cycles(graph) == [["pkg.high.two", "pkg.low", "pkg.low.one"]]
    assert cycles(package_graph(graph)) == [["high", "low"]]


def test_no_cycle_is_no_cycle(tmp_path):
    root = _tree(tmp_path, {"a.py": "from .b import x\nimport sys\n", "b.py": "x = 1\n"})
    assert cycles(import_graph(root)) == []


if __name__ == "__main__":  # pragma: no cover
    print("file-level cycles:", cycles(GRAPH))
    print("package-level cycles:", cycles(package_graph(GRAPH)))
    sys.exit(0)


def local_import_blocks(root: Path = ROOT):
    """(file, first line, the imported top-level names, commented) for every block of consecutive import
    statements inside a function: commented when a line of the block or the line right above it says why."""
    for path in sorted(root.rglob("*.py")):
        src = path.read_text(encoding="utf-8").splitlines()
        lines: dict[int, str] = {}
        for fn in ast.walk(ast.parse("\n".join(src), str(path))):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, ast.Import):
                        for ln in range(node.lineno, node.end_lineno + 1):
                            lines[ln] = node.names[0].name.split(".")[0]
                    elif isinstance(node, ast.ImportFrom):
                        for ln in range(node.lineno, node.end_lineno + 1):
                            lines[ln] = "." if node.level else (node.module or "").split(".")[0]
        block: list[int] = []
        for ln in sorted(lines) + [None]:
            if block and (ln is None or any(src[i - 1].strip() for i in range(block[-1] + 1, ln))):
                above = src[block[0] - 2].strip() if block[0] > 1 else ""
                commented = above.startswith("#") or any("#" in src[i - 1] for i in block)
                yield path, block[0], sorted({lines[i] for i in block}), commented
                block = []
            if ln is not None:
                block.append(ln)


def test_an_import_inside_a_function_says_why():
    """issue 25: an import inside a function hides a dependency from the reader; it stays only where it
    keeps a heavy or optional dependency (or a costly import) off an import path, with a comment saying so
    (docs/architecture.md "Imports inside functions"). The standard library is imported at the top."""
    stdlib = set(sys.stdlib_module_names) - {"tomllib"}   # tomllib: tomli before Python 3.11
    silent, stdlib_inside = [], []
    for path, line, names, commented in local_import_blocks():
        where = f"{path.relative_to(ROOT.parent)}:{line} {', '.join(names)}"
        if not commented:
            silent.append(where)
        if any(n in stdlib for n in names) and not commented:
            stdlib_inside.append(where)
    assert not silent, "imports inside functions without a comment saying why:\n" + "\n".join(silent)
    assert not stdlib_inside, "\n".join(stdlib_inside)


def test_a_silent_import_inside_a_function_is_found(tmp_path):
    pkg = tmp_path / "distctrl"
    pkg.mkdir()
    (pkg / "a.py").write_text("def f():\n    import os\n    return os\n\n\ndef g():\n"
                              "    # numba: the [batch] extra, only here\n    import numba\n    return numba\n")
    found = list(local_import_blocks(pkg))
    assert [(line, names, commented) for _, line, names, commented in found] == [(2, ["os"], False),
                                                                                (8, ["numba"], True)]
