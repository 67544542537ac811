"""``distctrl serve SCENARIO`` (ADS, and the live page with ``--ui``) and ``distctrl ui SCENARIO`` (the
same with the page, opened in the browser); :func:`serve_session`, the session loop both commands share
(docs/serve.md)."""
from __future__ import annotations

import logging
import sys
import webbrowser

import click

from ..ads.devices import AdsEndpoint
from ..errors import DistCtrlError
from ..serve.machine import ServedMachine
from ..serve.session import catch_sigterm, restore_sigterm, run_until
from ..sim.scenario import load_scenario
from .common import AMS_NET_ID, NETWORK, PORT, Finite, emit_json, fail


def serve_session(scenario: str, *, host: str, port: int, allowed: tuple[str, ...], net_id: str,
                  duration: float | None, no_discovery: bool, ui: bool, ui_port: int, export_dir: str,
                  open_browser: bool = False, as_json: bool = False, rt_priority: int = 10,
                  speed: float = 1.0) -> None:
    """Serve SCENARIO over ADS (and the live page with ``ui``) until ``duration``, Ctrl-C or SIGTERM;
    print the cycle's lateness at the end (and what stopped the session). All three are a normal end:
    exit code 0 (docs/serve.md)."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    logging.getLogger("bokeh").setLevel(logging.WARNING)
    logging.getLogger("tornado.access").setLevel(logging.WARNING)
    page = None
    previous_handler = catch_sigterm()
    try:
        served = ServedMachine(load_scenario(scenario), rt_priority=rt_priority, speed=speed)
        ads = AdsEndpoint(served, host=host, port=port, allowed=allowed, net_id=net_id,
                          discovery_port=None if no_discovery else 48899)
        if ui:
            from ..ui.app import UiServer  # Bokeh, the [ui] extra: loaded only for the page

            # the page's server starts before the cycle does: importing and setting up Bokeh is heavy
            page = UiServer(served, host=host, port=ui_port, allowed=allowed, export_dir=export_dir)
            try:
                page.start()
            except OSError as exc:
                fail(f"cannot serve the live page on {host}:{ui_port}: {exc.strerror or exc} "
                     "(--ui-port chooses another port)")
        try:
            served.start()
        except BaseException as exc:
            if page is not None:
                page.stop()
            if isinstance(exc, OSError):          # the ADS port cannot be bound: name the address
                fail(f"cannot serve ADS on {host}:{port}: {exc.strerror or exc} (--port chooses another port, "
                     "--host another address of this machine)")
            raise
    except (DistCtrlError, OSError, ValueError) as exc:
        restore_sigterm(previous_handler)
        fail(str(exc))
    except BaseException:
        restore_sigterm(previous_handler)
        raise
    if not as_json:
        pace = "" if speed == 1.0 else f", {speed:g}x real time"
        click.echo(f"serving {served.scenario.name}: ADS {net_id} on {host}:{ads.server.port}, "
                   f"allowed {', '.join(allowed)}{pace}; Ctrl-C or SIGTERM stops")
    if page is not None:
        if not as_json:
            click.echo(f"live page: {page.url}")
        if open_browser:
            if not webbrowser.open(page.url) and not as_json:
                click.echo(f"no browser could be started here: open {page.url} yourself", err=True)
    try:
        stopped_by = run_until(served, duration)
    finally:
        restore_sigterm(previous_handler)
    if page is not None:
        page.stop()
    stats = served.stop()
    if as_json:
        emit_json({"scenario": scenario, "ads": f"{host}:{ads.server.port}", "net_id": net_id,
                   "cycle_thread": served.loop.scheduling,
                   "ui_url": page.url if page is not None else None,
                   "ui_sessions": page.sessions if page is not None else 0, "stopped_by": stopped_by,
                   "speed": served.speed, "cycle_period_ms": served.loop.cycle_time * 1e3,
                   "machine_seconds": served.machine.cycle * served.machine.T, "cycle_lateness": stats})
        return
    end = f"after --duration {duration:g} s" if stopped_by == "duration" else f"by {stopped_by}"
    click.echo(f"stopped {end}")
    click.echo("cycle jitter: " + ", ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}"
                                           for k, v in stats.items()))


@click.command("serve")
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to listen on (ADS and the --ui page).")
@click.option("--port", default=48898, show_default=True, type=PORT, help="AMS/TCP port (0: a free port).")
@click.option("--allow", "allowed", multiple=True, default=["127.0.0.0/8"], show_default=True,
              type=NETWORK,
              help="Client address or network allowed to connect (like an ADS route; also to the --ui page); "
                   "repeat for more.")
@click.option("--net-id", default="127.0.0.1.1.1", show_default=True, type=AMS_NET_ID,
              help="AMS NetId of the served CNC.")
@click.option("--duration", type=Finite(0.0, min_open=True), default=None,
              help="Stop after this many seconds (default: until Ctrl-C or SIGTERM).")
@click.option("--no-discovery", is_flag=True,
              help="Do not answer route discovery and add-route on UDP 48899 (answered by default, "
                   "to the --allow networks).")
@click.option("--ui", "with_ui", is_flag=True,
              help="Also serve the live page (scope, object browser, PLC panel, machine view; docs/ui.md).")
@click.option("--ui-port", default=8050, show_default=True, type=click.IntRange(0, 65535),
              help="--ui: HTTP port of the live page (0: a free port).")
@click.option("--export-dir", default=".", show_default=True, type=click.Path(file_okay=False),
              help="--ui: folder the scope's Export CSV writes its trace files to.")
@click.option("--rt-priority", default=10, show_default=True, type=click.IntRange(0, 99),
              help="Run the 1 ms cycle thread with the real-time policy SCHED_FIFO at this priority where the "
                   "OS allows it (root, CAP_SYS_NICE or an rtprio limit; otherwise one warning and normal "
                   "priority); 0: normal priority.")
@click.option("--speed", default=1.0, show_default=True, type=Finite(0.0, 100.0, min_open=True),
              help="Machine seconds per wall-clock second: 3 runs the machine 3x faster than real time, as far "
                   "as the CPU allows (notification stamps stay in machine time); 0.5 half as fast.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object at the end (addresses, page sessions, speed, machine seconds, "
                   "cycle lateness in µs).")
def serve(scenario: str, host: str, port: int, allowed: tuple[str, ...], net_id: str, duration: float | None,
          no_discovery: bool, with_ui: bool, ui_port: int, export_dir: str, rt_priority: int, speed: float,
          as_json: bool) -> None:
    """Run SCENARIO.toml in real time and serve it over ADS (CNC objects on AMS port 551, the PLC
    interface and V.E. variables by symbol name on port 851; route discovery and add-route on UDP
    48899); with --ui also the live page. Reports the cycle jitter at the end."""
    serve_session(scenario, host=host, port=port, allowed=allowed, net_id=net_id, duration=duration,
                  no_discovery=no_discovery, ui=with_ui, ui_port=ui_port, export_dir=export_dir, as_json=as_json,
                  rt_priority=rt_priority, speed=speed)


RT_OPTION = click.option(
    "--rt-priority", default=10, show_default=True, type=click.IntRange(0, 99),
    help="Run the 1 ms cycle thread with the real-time policy SCHED_FIFO at this priority where the OS "
         "allows it (root, CAP_SYS_NICE or an rtprio limit; otherwise one warning and normal priority); "
         "0: normal priority. Keeps the cycle's timing while a browser draws the live page.")


@click.command("ui")
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--host", default="127.0.0.1", show_default=True, help="Address the page and ADS listen on.")
@click.option("--ui-port", default=8050, show_default=True, type=click.IntRange(0, 65535),
              help="HTTP port of the live page (0: a free port).")
@click.option("--port", default=48898, show_default=True, type=PORT, help="AMS/TCP port (0: a free port).")
@click.option("--allow", "allowed", multiple=True, default=["127.0.0.0/8"], show_default=True,
              type=NETWORK,
              help="Client address or network allowed to connect to the page and over ADS; repeat for more.")
@click.option("--net-id", default="127.0.0.1.1.1", show_default=True, type=AMS_NET_ID,
              help="AMS NetId of the served CNC.")
@click.option("--duration", type=Finite(0.0, min_open=True), default=None,
              help="Stop after this many seconds (default: until Ctrl-C or SIGTERM).")
@click.option("--no-discovery", is_flag=True, help="Do not answer route discovery on UDP 48899.")
@click.option("--export-dir", default=".", show_default=True, type=click.Path(file_okay=False),
              help="Folder the scope's Export CSV writes its trace files to.")
@click.option("--no-browser", is_flag=True, help="Only print the page's address, open no browser.")
@RT_OPTION
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object at the end (addresses, page sessions, cycle lateness in µs).")
def ui_cmd(scenario: str, host: str, ui_port: int, port: int, allowed: tuple[str, ...], net_id: str,
           duration: float | None, no_discovery: bool, export_dir: str, no_browser: bool, rt_priority: int,
           as_json: bool) -> None:
    """Serve SCENARIO.toml in real time over ADS with the live page (scope, object browser, PLC panel,
    machine view; docs/ui.md) and open the page in the browser."""
    serve_session(scenario, host=host, port=port, allowed=allowed, net_id=net_id, duration=duration,
                  no_discovery=no_discovery, ui=True, ui_port=ui_port, export_dir=export_dir,
                  open_browser=not no_browser, as_json=as_json, rt_priority=rt_priority)
    sys.stdout.flush()
