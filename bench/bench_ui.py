"""Benchmark: the live page's cost to the served 1 ms cycle, and its update latency (issue 17, "Speed").

In one process: the served machine (examples/scenarios/serve_z.toml, 1 ms cycle) with the live page's
Bokeh server (distctrl/ui). Headless Chromium (Debian's, driven by Playwright) opens pages on it.

Headless Chromium is driven by Playwright from a second process (this script with ``--browser``), so
the measured process holds what ``distctrl serve --ui`` holds.

1. **Cycle lateness under load.** The cycle-start lateness p99 over ``--seconds`` with the page server
   running and no page open, then over the same time with two pages open on the scope (streaming at
   up to 20 frames/s: fewer when the browser has not drawn the last ones, docs/ui.md "Keeping up"),
   in alternating windows (none, two, none, two, ...) so that both see the same machine
   state. Target: p99 with pages <= 1.2x p99 without.
2. **Page update latency** (a value changes in the machine -> the page shows it): the bench sets the
   path override in the machine (under the machine's lock, wall clock noted) to a new value; a
   MutationObserver in each page notes the wall clock of the next animation frame after the status
   line shows it. Target: median <= 100 ms.

Results: bench/ui.json, merged into bench/results.json (keys ``ui_*``) and a section of
bench/RESULTS.md. ``--quick``: shorter windows (smoke test).
"""
from __future__ import annotations

import argparse
import json
import pathlib
import re
import statistics
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from _results import merge_results  # noqa: E402

from distctrl.ads.devices import serve_over_ads  # noqa: E402
from distctrl.sim.scenario import load_scenario  # noqa: E402
from distctrl.ui import UiServer  # noqa: E402

SCENARIO = ROOT / "examples" / "scenarios" / "serve_z.toml"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--headless", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
P99_RATIO = 1.2
LATENCY_MEDIAN_MS = 100.0
SECTION = "## Live page (bench_ui.py)"

#: notes the wall clock of the first animation frame after the status line's override changes
OBSERVER_JS = """() => {
  window.__seen = [];
  const find = (root) => { for (const h of root.querySelectorAll('*')) {
      if (h.classList && h.classList.contains('override')) return h;
      if (h.shadowRoot) { const e = find(h.shadowRoot); if (e) return e; } } return null; };
  let last = null;
  const watch = () => { const e = find(document);
    if (e) { const v = e.textContent; if (v !== last) { last = v;
      requestAnimationFrame(() => window.__seen.push([v, Date.now()])); } } };
  // the override is a fixed element whose text the page's script sets (distctrl.ui.live); the whole
  // tree is watched all the same, so that the bench also measures a page that re-renders it
  const observe = (root) => { new MutationObserver(watch).observe(root, {subtree: true, childList: true,
      characterData: true}); for (const h of root.querySelectorAll('*')) if (h.shadowRoot) observe(h.shadowRoot); };
  observe(document); watch();
}"""


def lateness_window(served, seconds: float) -> list[float]:
    stats = served.loop.stats
    start = len(stats._samples)
    time.sleep(seconds)
    return list(stats._samples[start:])


def p99(samples: list[float]) -> float:
    s = sorted(samples)
    return s[min(len(s) - 1, int(0.99 * len(s)))] if s else float("nan")


def browser_child(url: str) -> None:
    """The browser side (its own process): commands on stdin, one JSON answer per line on stdout."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        pages = []
        for line in sys.stdin:
            cmd = line.split()
            answer = None
            if cmd[0] == "open":
                for _ in range(int(cmd[1])):
                    page = browser.new_page(viewport={"width": 1300, "height": 900})
                    page.goto(url)
                    page.locator(".scope-plot").first.wait_for()
                    if "observe" in cmd:
                        page.locator(".override").first.wait_for()
                        page.evaluate(OBSERVER_JS)
                    pages.append(page)
            elif cmd[0] == "close":
                for page in pages:
                    page.close()
                pages = []
            elif cmd[0] == "collect":
                answer = [page.evaluate("window.__seen") for page in pages]
            elif cmd[0] == "quit":
                print("null", flush=True)
                break
            print(json.dumps(answer), flush=True)
        browser.close()


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short windows (smoke test)")
    ap.add_argument("--seconds", type=float, default=None, help="length of each window (default 5 s, quick 2 s)")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "bench")
    ap.add_argument("--browser", metavar="URL", help=argparse.SUPPRESS)     # the browser process
    ap.add_argument("--rt-priority", type=int, default=10,
                    help="the cycle thread's SCHED_FIFO priority, as `distctrl serve` (0: normal priority)")
    args = ap.parse_args(argv)
    if args.browser:
        browser_child(args.browser)
        return {}
    window = args.seconds or (2.0 if args.quick else 5.0)
    rounds = 2 if args.quick else 4
    changes = 10 if args.quick else 40
    served = serve_over_ads(load_scenario(SCENARIO), port=0, discovery_port=None, rt_priority=args.rt_priority)
    ui = UiServer(served, port=0, export_dir=args.out / "ui_exports")
    served.start()
    ui.start()
    none_s: list[float] = []
    two_s: list[float] = []
    latencies: list[float] = []
    # the browser is driven from a process of its own (this script with --browser URL): the served
    # process then holds only what `distctrl serve --ui` holds, not Playwright's client too
    child = subprocess.Popen([sys.executable, __file__, "--browser", ui.url], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True, bufsize=1)

    def ask(command: str):
        child.stdin.write(command + "\n")
        child.stdin.flush()
        return json.loads(child.stdout.readline())

    try:
        ask("hello")
        for _ in range(rounds):
            none_s += lateness_window(served, window)
            ask("open 2")
            time.sleep(1.0)                        # the pages are up and streaming
            two_s += lateness_window(served, window)
            ask("close")
            time.sleep(1.0)                        # their sessions are gone
        # update latency: two pages, override changes noted in the page
        ask("open 2 observe")
        time.sleep(1.5)
        sent = []
        for i in range(changes):
            value = 0.50 + 0.01 * (i % 40)
            with served.lock:
                served.machine.channel_override = value
                t = time.time() * 1000.0
            sent.append((f"{value * 100:.0f}", t))
            time.sleep(0.25 + 0.013 * (i % 7))     # not in step with the pages' frames
        time.sleep(0.5)
        for seen in ask("collect"):
            for text, t_sent in sent:
                t_seen = next((ts for v, ts in seen if v == text and ts >= t_sent - 1.0), None)
                if t_seen is not None:
                    latencies.append(t_seen - t_sent)
        ask("quit")
    finally:
        child.kill()
        child.wait()
        ui.stop()
        served.stop()
    p_none, p_two = p99(none_s), p99(two_s)
    ratio = p_two / p_none if p_none > 0 else float("inf")
    med = statistics.median(latencies) if latencies else float("nan")
    res = {"ui_p99_lateness_no_pages_us": p_none * 1e6, "ui_p99_lateness_two_pages_us": p_two * 1e6,
           "ui_p99_ratio": ratio, "ui_p99_target": P99_RATIO,
           "ui_median_lateness_no_pages_us": statistics.median(none_s) * 1e6,
           "ui_median_lateness_two_pages_us": statistics.median(two_s) * 1e6,
           "ui_max_lateness_two_pages_us": max(two_s) * 1e6,
           "ui_cycles_late_over_1ms_two_pages": sum(1 for s in two_s if s > 1e-3),
           "ui_cycles_measured": [len(none_s), len(two_s)],
           "ui_update_latency_median_ms": med,
           "ui_update_latency_p90_ms": sorted(latencies)[int(0.9 * len(latencies))] if latencies else None,
           "ui_update_latency_samples": len(latencies), "ui_update_latency_sent": changes * 2,
           "ui_update_latency_target_ms": LATENCY_MEDIAN_MS, "ui_quick": args.quick,
           "ui_window_s": window, "ui_rounds": rounds, "ui_cycle_thread": served.loop.scheduling}
    ok_ratio, ok_lat = ratio <= P99_RATIO, med <= LATENCY_MEDIAN_MS
    lines = ["", SECTION, "",
             f"Served machine serve_z.toml (1 ms cycle) with the page server; {rounds} alternating windows of "
             f"{window:g} s without pages and with two pages on the scope (headless Chromium); cycle thread "
             f"{served.loop.scheduling}.", "",
             "| measurement | value | target | result |", "|---|---:|---:|---|",
             f"| cycle-start lateness p99, no page open | {p_none * 1e6:.0f} µs | | |",
             f"| cycle-start lateness p99, two pages open | {p_two * 1e6:.0f} µs | | |",
             f"| **p99 two pages / no page** | **{ratio:.2f}×** | ≤ {P99_RATIO}× | {'PASS' if ok_ratio else 'FAIL'} |",
             f"| cycles started > 1 ms late with two pages | {res['ui_cycles_late_over_1ms_two_pages']} of "
             f"{len(two_s)} | | |",
             f"| **page update latency, median** ({len(latencies)} of {changes * 2}) | **{med:.0f} ms** | "
             f"≤ {LATENCY_MEDIAN_MS:.0f} ms | {'PASS' if ok_lat else 'FAIL'} |",
             f"| page update latency, p90 | {res['ui_update_latency_p90_ms'] or float('nan'):.0f} ms | | |"]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "ui.json").write_text(json.dumps(res, indent=2) + "\n")
    md = args.out / "RESULTS.md"
    if md.exists():
        text = re.sub(r"\n*" + re.escape(SECTION) + r"\n.*?(?=\n## |\Z)", "", md.read_text(encoding="utf-8"),
                      flags=re.DOTALL)
        md.write_text(text.rstrip("\n") + "\n", encoding="utf-8")
    merge_results(args.out, res, lines)
    print("\n".join(lines))
    return res


if __name__ == "__main__":
    main()
