"""The screenshots of docs/ui.md: each view of the live page over examples/scenarios/serve_z.toml,
taken by headless Chromium (Debian's, driven by Playwright) into docs/img/ui_*.png.

The machine is served as `distctrl serve --ui` does; after 3 s the page's PLC panel selects distance
control on Z (ON, SET_POS 40 mm), a write of DIST_CTRL::kp waits for its adoption, and a short sensor
jump shows a state change in the scope. Run: ``python tools/ui_screenshots.py [--out docs/img]``.
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from distctrl.ads.devices import serve_over_ads  # noqa: E402
from distctrl.sim.scenario import load_scenario  # noqa: E402
from distctrl.ui import UiServer  # noqa: E402

ARGS = ["--no-sandbox", "--headless", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars"]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "docs" / "img")
    args = ap.parse_args(argv)
    from playwright.sync_api import sync_playwright

    served = serve_over_ads(load_scenario(ROOT / "examples" / "scenarios" / "serve_z.toml"), port=0,
                           discovery_port=None)
    ui = UiServer(served, port=0, export_dir="/tmp")
    ui.start()
    served.start()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS)
            page = browser.new_page(viewport={"width": 1300, "height": 820})
            page.goto(ui.url)
            page.locator(".scope-plot").first.wait_for()
            time.sleep(2.0)

            def tab(name):
                page.locator(".bk-tab", has_text=name).first.click()
                page.wait_for_timeout(600)

            tab("PLC panel")
            page.locator(".plc-Z-ON button").click()
            time.sleep(2.5)
            tab("Object browser")
            page.locator(".obj-name select").select_option("DIST_CTRL::kp")
            page.locator(".obj-value input").fill("0.8")
            page.locator(".obj-value input").press("Enter")
            page.locator(".obj-write button").click()
            page.wait_for_timeout(800)
            page.screenshot(path=str(args.out / "ui_objects.png"))
            tab("PLC panel")
            page.locator(".plc-Z-FREEZE button").click()
            time.sleep(0.5)
            page.locator(".plc-Z-ON button").click()
            time.sleep(1.0)
            page.locator(".plc-fault-value-jump input").fill("0.3")       # a small jump: a step in the reading
            page.locator(".plc-fault-value-jump input").press("Enter")
            page.locator(".plc-fault-jump button").click()
            time.sleep(1.5)
            page.screenshot(path=str(args.out / "ui_plc.png"), full_page=True)
            tab("Scope")
            time.sleep(1.0)
            page.screenshot(path=str(args.out / "ui_scope.png"))
            tab("Machine view")
            time.sleep(1.0)
            page.screenshot(path=str(args.out / "ui_machine.png"))
            browser.close()
    finally:
        ui.stop()
        served.stop()
    for name in ("scope", "objects", "plc", "machine"):
        print(args.out / f"ui_{name}.png")


if __name__ == "__main__":
    main()
