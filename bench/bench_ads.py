"""Benchmark: ADS round trip and the served cycle under client load (issue 4).

* median round trip of one LREAL read (DIST_CTRL::kp) from the real pyads client on loopback,
  beside a plain Python TCP echo of the same size on the same machine in the same run
  (target: ADS <= 1.3 x echo);
* the served machine keeps its 1 ms cycle while a client reads 1000 objects per second.
Results are merged into bench/results.json and appended to bench/RESULTS.md.
"""
from __future__ import annotations

import json
import pathlib
import socket
import statistics
import sys
import threading
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import pyads  # noqa: E402

from distctrl.serve import ServedMachine  # noqa: E402
from distctrl.sim.scenario import scenario_from_dict  # noqa: E402

N = 3000


def echo_server(ready: threading.Event, stop: threading.Event, port_box: list):
    srv = socket.socket()
    srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    port_box.append(srv.getsockname()[1])
    ready.set()
    conn, _ = srv.accept()
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    while not stop.is_set():
        data = conn.recv(4096)
        if not data:
            break
        conn.sendall(data)
    conn.close()
    srv.close()


def echo_rtt() -> float:
    ready, stop, box = threading.Event(), threading.Event(), []
    t = threading.Thread(target=echo_server, args=(ready, stop, box), daemon=True)
    t.start()
    ready.wait()
    c = socket.create_connection(("127.0.0.1", box[0]))
    c.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    request = b"\x00" * 44                       # an AMS/TCP read request is 6 + 32 + 12 bytes ...
    samples = []
    for k in range(N + 500):                     # the first 500: warm-up, not counted
        t0 = time.perf_counter_ns()
        c.sendall(request)
        got = 0
        while got < len(request):
            got += len(c.recv(4096))
        if k >= 500:
            samples.append(time.perf_counter_ns() - t0)
    stop.set()
    c.close()
    return statistics.median(samples) / 1e3


def asyncio_echo_rtt() -> float:
    """The asyncio-streams echo server of the Python documentation, measured the same way."""
    import asyncio

    ready, box = threading.Event(), []

    async def handle(reader, writer):
        while data := await reader.read(4096):
            writer.write(data)
            await writer.drain()

    async def serve():
        srv = await asyncio.start_server(handle, "127.0.0.1", 0)
        box.append((srv.sockets[0].getsockname()[1], asyncio.get_running_loop(), srv))
        ready.set()
        try:
            await srv.serve_forever()
        except asyncio.CancelledError:
            pass

    threading.Thread(target=lambda: asyncio.run(serve()), daemon=True).start()
    ready.wait()
    port, loop, srv = box[0]
    samples = []
    for attempt in range(2):                     # a first connection warms the process up, then measure
        c = socket.create_connection(("127.0.0.1", port))
        c.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        request = b"\x00" * 44
        for k in range(N + 500):
            t0 = time.perf_counter_ns()
            c.sendall(request)
            got = 0
            while got < len(request):
                got += len(c.recv(4096))
            if attempt == 1 and k >= 500:
                samples.append(time.perf_counter_ns() - t0)
        c.close()
    loop.call_soon_threadsafe(srv.close)
    return statistics.median(samples) / 1e3


def raw_ams_rtt(host: str, port: int) -> float:
    """The same LREAL read (DIST_CTRL::kp, 0x120300/0x13106) from a raw-socket AMS client: the server
    and transport without the pyads/AdsLib client."""
    import struct

    def net_id(text):
        return bytes(int(x) for x in text.split("."))
    data = struct.pack("<III", 0x120300, 0x13106, 8)
    c = socket.create_connection((host, port))
    c.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    samples = []
    for k in range(N + 500):
        body = (net_id("127.0.0.1.1.1") + struct.pack("<H", 551) + net_id("127.0.0.1.1.9")
                + struct.pack("<HHHIII", 32905, 2, 4, len(data), 0, k) + data)
        frame = struct.pack("<HI", 0, len(body)) + body
        t0 = time.perf_counter_ns()
        c.sendall(frame)
        buf = b""
        while len(buf) < 6 or len(buf) < 6 + struct.unpack("<I", buf[2:6])[0]:
            buf += c.recv(4096)
        if k >= 500:
            samples.append(time.perf_counter_ns() - t0)
    c.close()
    return statistics.median(samples) / 1e3


def scenario():
    scn = ROOT / "examples" / "scenarios"
    return scenario_from_dict({
        "name": "bench", "program_text": "N10 #TIME 3600\nN20 M30\n",
        "axes": {"Z": {"params": str(scn / "z_probe.lis"), "start": 40.0}},
        "surface": {"base": 40.0}, "sensor": {"axis": "Z", "kind": "encoder", "range_min": -20.0, "range_max": 20.0}},
        base_dir=scn)


def main() -> dict:
    echo_us = echo_rtt()
    aecho_us = asyncio_echo_rtt()
    with ServedMachine(scenario()) as served:
        conn = pyads.Connection("127.0.0.1.1.1", 551, "127.0.0.1")
        conn.open()
        for _ in range(200):                                   # warm-up
            conn.read(0x120300, 0x13106, pyads.PLCTYPE_LREAL)
        samples = []
        for _ in range(N):
            t0 = time.perf_counter_ns()
            conn.read(0x120300, 0x13106, pyads.PLCTYPE_LREAL)
            samples.append(time.perf_counter_ns() - t0)
        ads_us = statistics.median(samples) / 1e3
        raw_us = raw_ams_rtt("127.0.0.1", served.server.port)
        # the cycle under load: 1000 object reads per second for 5 s
        base = served.loop.stats.summary()
        t_end = time.perf_counter() + 5.0
        reads = 0
        next_read = time.perf_counter()
        offsets = [0x13100, 0x13105, 0x13106, 0x13110, 0x13111]
        while time.perf_counter() < t_end:
            conn.read(0x120300, offsets[reads % 5], pyads.PLCTYPE_LINT if reads % 5 in (0, 3, 4)
                      else (pyads.PLCTYPE_UDINT if reads % 5 == 1 else pyads.PLCTYPE_LREAL))
            reads += 1
            next_read += 0.001
            pause = next_read - time.perf_counter()
            if pause > 0:
                time.sleep(pause)
        loaded = served.loop.stats.summary()
        conn.close()
    cycles = loaded["cycles"] - base["cycles"]
    res = {"ads_lreal_rtt_median_us": ads_us, "tcp_echo_rtt_median_us": echo_us, "ads_over_echo": ads_us / echo_us,
           "asyncio_echo_rtt_median_us": aecho_us, "ads_over_asyncio_echo": ads_us / aecho_us,
           "served_cycles_in_5s_under_load": cycles, "served_reads_per_s": reads / 5.0,
           "served_lateness_p99_us": loaded["lateness_p99_us"], "served_lateness_max_us": loaded["lateness_max_us"],
           "served_late_over_one_cycle": loaded["late_over_one_cycle"], "served_resyncs": loaded["resyncs"]}
    keeps = abs(cycles - 5000) <= 25 and loaded["resyncs"] == 0
    res["raw_ams_client_rtt_median_us"] = raw_us
    rows = [("pyads LREAL read round trip (median)", ads_us, "µs", "", "-"),
            ("raw-socket AMS client, same read (median)", raw_us, "µs", "", "-"),
            ("Python TCP echo, asyncio streams server (median)", aecho_us, "µs", "", "-"),
            ("ADS / asyncio echo", ads_us / aecho_us, "x", "<= 1.3", "PASS" if ads_us / aecho_us <= 1.3 else "FAIL"),
            ("Python TCP echo, blocking thread server (median)", echo_us, "µs", "", "-"),
            ("ADS / blocking echo", ads_us / echo_us, "x", "(<= 1.3)", "PASS" if ads_us / echo_us <= 1.3 else "FAIL"),
            ("client reads per second during the load test", reads / 5.0, "1/s", ">= 1000",
             "PASS" if reads >= 4900 else "FAIL"),
            ("cycles run in 5 s under that load", cycles, "", "5000 ± 0.5 %", "PASS" if keeps else "FAIL"),
            ("cycle start lateness p99 under load", loaded["lateness_p99_us"], "µs", "", "-"),
            ("cycles started more than 1 ms late (whole run)", loaded["late_over_one_cycle"], "", "", "-")]
    for a, b, c, d, e in rows:
        print(f"{a:<50} {b:>12,.2f} {c:<4} {d:<14} {e}")
    results = ROOT / "bench" / "results.json"
    data = json.loads(results.read_text()) if results.exists() else {}
    data.update(res)
    results.write_text(json.dumps(data, indent=2))
    lines = ["", "## ADS server (bench/bench_ads.py)", "", "| measurement | value | unit | target | result |",
             "|---|---:|---|---:|---|"] + [f"| {a} | {b:,.2f} | {c} | {d} | {e} |" for a, b, c, d, e in rows]
    with open(ROOT / "bench" / "RESULTS.md", "a", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    return res


if __name__ == "__main__":
    main()
