"""Where every benchmark's figures go: merged into ``results.json`` (keys of its own) and its section
appended to ``RESULTS.md`` (bench_core.py starts both afresh each `make bench`)."""
from __future__ import annotations

import json
from pathlib import Path


def merge_results(out_dir: Path, res: dict, lines: list[str]) -> None:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    results = out_dir / "results.json"
    data = json.loads(results.read_text()) if results.exists() else {}
    data.update(res)
    results.write_text(json.dumps(data, indent=2))
    with open(out_dir / "RESULTS.md", "a", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
