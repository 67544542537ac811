"""The layer map of distctrl/ (docs/architecture.md): the packages on their floors and who imports whom,
read from the source with ``ast`` the way tests/test_structure.py reads it (every import counts, also
inside functions and under ``if TYPE_CHECKING:``).

``python tools/layer_map.py`` prints the floors as a markdown table; ``--svg PATH`` also draws the map
(matplotlib) to PATH; ``make docs`` writes docs/architecture-layers.svg. A package's floor is one above
the highest floor it imports from (floor 1 imports nothing of distctrl), so every arrow points down.
"""
from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "distctrl"


def package_graph(root: Path = PKG) -> dict[str, set[str]]:
    """package -> the packages of distctrl it imports (sub-packages of ``root``; top-level modules too)."""
    files = {}
    for p in root.rglob("*.py"):
        parts = (root.name, *p.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        files[".".join(parts)] = p

    def resolve(name: str) -> str | None:
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    def pkg(mod: str) -> str:
        parts = mod.split(".")
        return parts[1] if len(parts) > 1 else parts[0]

    graph: dict[str, set[str]] = {pkg(m): set() for m in files if m != root.name}
    for mod, path in files.items():
        base_pkg = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = base_pkg.split(".")
                    parts = parts[: len(parts) - (node.level - 1)]
                    base = ".".join(parts + ([base] if base else []))
                names = [f"{base}.{a.name}" for a in node.names] + [base]
            else:
                continue
            for n in names:
                target = resolve(n)
                if target and target.startswith(root.name + ".") and pkg(target) != pkg(mod) and mod != root.name:
                    graph[pkg(mod)].add(pkg(target))
    return graph


def floors(graph: dict[str, set[str]]) -> dict[str, int]:
    """package -> floor (1 + the highest floor of what it imports); raises ValueError on a cycle."""
    out: dict[str, int] = {}
    visiting: set[str] = set()

    def floor(p: str) -> int:
        if p in out:
            return out[p]
        if p in visiting:
            raise ValueError(f"import cycle through {p}")
        visiting.add(p)
        out[p] = 1 + max((floor(q) for q in graph.get(p, ())), default=0)
        visiting.discard(p)
        return out[p]

    for p in sorted(graph):
        floor(p)
    return out


def table(graph: dict[str, set[str]]) -> str:
    fl = floors(graph)
    rows = ["| floor | package | imports (of distctrl) |", "|---|---|---|"]
    for p in sorted(graph, key=lambda q: (fl[q], q)):
        deps = ", ".join(f"`{q}`" for q in sorted(graph[p], key=lambda q: (fl[q], q))) or "nothing"
        rows.append(f"| {fl[p]} | `{p}` | {deps} |")
    return "\n".join(rows) + "\n"


def draw(graph: dict[str, set[str]], path: Path) -> None:
    """The packages as boxes on their floors (top: the command line, bottom: the vocabulary) and an
    arrow from every package to each package it imports."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

    matplotlib.rcParams["svg.hashsalt"] = "distctrl"          # the same file for the same graph
    fl = floors(graph)
    top = max(fl.values())
    rows: dict[int, list[str]] = {}
    for p in sorted(graph):
        rows.setdefault(fl[p], []).append(p)
    width = max(len(r) for r in rows.values())
    pos = {}
    for f, names in rows.items():
        for i, p in enumerate(names):
            pos[p] = ((i + 0.5) * width / len(names), f)
    fig = Figure(figsize=(1.5 * width + 1.5, 0.9 * top + 1.0))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(-0.2, width + 0.2)
    ax.set_ylim(0.4, top + 0.6)
    ax.axis("off")
    for f in range(1, top + 1):
        ax.text(-0.15, f, f"{f}", ha="left", va="center", color="0.5", fontsize=9)
    w, h = 0.8, 0.34
    for a in sorted(graph):
        for b in sorted(graph[a]):
            (x0, y0), (x1, y1) = pos[a], pos[b]
            ax.add_patch(FancyArrowPatch((x0, y0 - h / 2), (x1, y1 + h / 2), arrowstyle="-|>", mutation_scale=8,
                                         color="0.55", linewidth=0.6, shrinkA=0, shrinkB=0, zorder=1,
                                         connectionstyle="arc3,rad=0.0"))
    for p, (x, y) in pos.items():
        ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h, boxstyle="round,pad=0.02", facecolor="#e8f0fa",
                                    edgecolor="#34609a", linewidth=1.0, zorder=2))
        ax.text(x, y, p, ha="center", va="center", fontsize=10, zorder=3)
    fig.savefig(path, format=path.suffix.lstrip(".") or "svg", metadata={"Date": None} if path.suffix == ".svg"
                else None)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--svg", type=Path, help="also draw the map to this file (.svg or .png)")
    args = ap.parse_args(argv)
    graph = package_graph()
    try:
        sys.stdout.write(table(graph))
    except ValueError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 1
    if args.svg:
        draw(graph, args.svg)
    return 0


if __name__ == "__main__":
    sys.exit(main())
