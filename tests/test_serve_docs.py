"""docs/serve.md's examples run as written against examples/scenarios/serve_z.toml served on
127.0.0.1:48898 (issue 14): the pyads example, where every `# -> value` comment is what the line
returns, and the ads-client (Node.js) example, whose printed lines are its `// -> value` comments."""
from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.ads import port_free

ROOT = Path(__file__).resolve().parents[1]
pytest.importorskip("pyads")

RUNNER = textwrap.dedent('''
    import re, sys
    from distctrl.ads.devices import serve_over_ads
    from distctrl.sim.scenario import load_scenario

    code = sys.stdin.read()
    with serve_over_ads(load_scenario(sys.argv[1]), host="127.0.0.1", net_id="127.0.0.1.1.1"):
        env = {}
        for line in code.splitlines():
            want = re.search(r"# -> (\\S+)", line)
            stmt = line.split("#", 1)[0].rstrip() if want else line
            if want:
                got = eval(stmt, env)
                print(f"CHECK {stmt.strip()!r} -> {got!r} (docs: {want.group(1)})")
                assert str(got) == want.group(1), (stmt, got, want.group(1))
            else:
                exec(line, env)
    print("DOCS OK")
''')


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_the_pyads_example_of_docs_serve_md_runs_as_written():
    if not port_free("127.0.0.1", 48898):
        pytest.skip("TCP 48898 on 127.0.0.1 is in use (the example connects there)")
    blocks = _python_blocks((ROOT / "docs" / "serve.md").read_text(encoding="utf-8"))
    assert blocks, "docs/serve.md has no python example"
    for code in blocks:
        res = subprocess.run([sys.executable, "-c", RUNNER, str(ROOT / "examples" / "scenarios" / "serve_z.toml")],
                             input=code, capture_output=True, text=True, cwd=ROOT, timeout=120)
        assert res.returncode == 0 and "DOCS OK" in res.stdout, res.stdout + res.stderr
        assert "CHECK" in res.stdout


def test_the_ads_client_example_of_docs_serve_md_runs_as_written():
    from distctrl.ads.devices import serve_over_ads
    from distctrl.sim.scenario import load_scenario
    from tests.ads.test_ads_client import NODE_DIR, node

    exe = node()                               # fails (never skips) if Node.js or ads-client is missing
    if not port_free("127.0.0.1", 48898):
        pytest.skip("TCP 48898 on 127.0.0.1 is in use (the example connects there)")
    blocks = re.findall(r"```js\n(.*?)```", (ROOT / "docs" / "serve.md").read_text(encoding="utf-8"), flags=re.S)
    assert len(blocks) == 1, "docs/serve.md should have one ads-client example"
    want = [m.group(1) for m in re.finditer(r"// -> (\S+)", blocks[0])]
    env = dict(os.environ, NODE_PATH=str(NODE_DIR / "node_modules"))
    with serve_over_ads(load_scenario(ROOT / "examples" / "scenarios" / "serve_z.toml"), host="127.0.0.1",
                       net_id="127.0.0.1.1.1"):
        res = subprocess.run([exe, "-e", blocks[0]], capture_output=True, text=True, env=env, timeout=60)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == want and want
