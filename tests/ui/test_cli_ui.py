"""``distctrl serve --ui`` and ``distctrl ui`` on the command line: the page's address, the JSON at the
end, and a page port in use as one error line."""
from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCN = str(ROOT / "examples" / "scenarios" / "serve_z.toml")
COMMON = ["--port", "0", "--no-discovery", "--duration", "1.5", "--rt-priority", "0"]


def distctrl(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "distctrl", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)


def test_serve_ui_prints_the_page_and_the_lateness():
    proc = distctrl("serve", SCN, "--ui", "--ui-port", "0", *COMMON)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "live page: http://127.0.0.1:" in proc.stdout
    assert "cycle jitter: cycles" in proc.stdout and "lateness_p99_us" in proc.stdout


def test_ui_json_without_browser():
    proc = distctrl("ui", SCN, "--ui-port", "0", "--no-browser", "--json", *COMMON)
    assert proc.returncode == 0, proc.stderr[-2000:]
    doc = json.loads(proc.stdout)
    assert doc["ui_url"].startswith("http://127.0.0.1:") and doc["ui_sessions"] == 0
    assert doc["cycle_thread"] == "normal" and doc["cycle_lateness"]["cycles"] > 1000


def test_a_page_port_in_use_is_one_error_line():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        proc = distctrl("serve", SCN, "--ui", "--ui-port", str(port), *COMMON)
    assert proc.returncode == 1
    assert f"error: cannot serve the live page on 127.0.0.1:{port}" in proc.stderr
    assert "Traceback" not in proc.stderr
