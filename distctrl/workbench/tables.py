"""Text tables of the workbench's metrics (filters, step responses): rich without colour, or plain ASCII."""
from __future__ import annotations

import io
from typing import Sequence


def render_table(columns: Sequence[str], rows: Sequence[Sequence[str]], title: str | None = None,
                 plain: bool = False) -> str:
    """``columns`` and already formatted ``rows`` as text; the first column left, the others right."""
    if plain:
        widths = [max([len(h)] + [len(row[i]) for row in rows]) for i, h in enumerate(columns)]

        def line(cells: Sequence[str]) -> str:
            return "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))
        out = ([title] if title else []) + [line(columns), "  ".join("-" * w for w in widths)]
        out += [line(row) for row in rows]
        return "\n".join(s.rstrip() for s in out) + "\n"
    # rich (0.1 s of import): only where a table or progress bar is printed
    from rich import box
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title, box=box.SIMPLE_HEAD, title_justify="left")
    table.add_column(columns[0], no_wrap=True)
    for h in columns[1:]:
        table.add_column(h, justify="right", no_wrap=True)
    for row in rows:
        table.add_row(*row)
    width = sum(max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(columns)) + 4 * len(columns) + 4
    buf = io.StringIO()
    Console(file=buf, width=max(width, len(title or "") + 2, 60), color_system=None, force_terminal=False,
            highlight=False, emoji=False, markup=False).print(table)
    return "\n".join(s.rstrip() for s in buf.getvalue().splitlines()) + "\n"
