// ads-client (npm, Node.js) against a served distctrl machine: the Node side of bench/bench_ads.py.
//
//   NODE_PATH=tests/ads/node/node_modules node bench/ads_client_bench.js rtt  <tcp port> <symbol> [rounds] [per round] [warm-up rounds]
//   NODE_PATH=tests/ads/node/node_modules node bench/ads_client_bench.js load <tcp port> <symbol> [seconds] [period ms]
//
// One default-mode session (port 851 of 127.0.0.1.1.1, as tests/ads/node/session.js connects).
//
// rtt: round trips of three reads of one symbol, in interleaved rounds (the order rotates every
//   round, so that each read sees the same machine state as the others):
//   - readValue(symbol): by name, after the first call from ads-client's cached symbol and data
//     type (a Read of the symbol's index group and offset, then the conversion to a JS value);
//   - readRawByPath(symbol): by name every time (ReadWrite 0xF004 "value by name");
//   - readRawByHandle(handle): by handle (Read 0xF005) of a handle made once by createVariableHandle.
//   Prints one JSON line: the median round trip (µs) of each, and the per-round medians.
//
// load: prints {"ready": true} once connected, waits for a line on stdin, then reads the symbol by
//   readValue every <period> ms for <seconds> s, and prints one JSON line: the reads done, errors,
//   the time the loop ran and the longest gap between two reads. Read k is due at start + k periods;
//   the loop sleeps (a timer, whole ms: no busy wait) only while ahead of that schedule, and a read
//   that is due follows the previous one at once (the reads catch up, as the pyads side does).
'use strict';
const { Client } = require('ads-client');

const [mode, port, symbol] = process.argv.slice(2, 5);
const args = process.argv.slice(5).map(Number);
const now = () => Number(process.hrtime.bigint()) / 1e3;                 // µs
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

function median(v) {
  const s = Float64Array.from(v).sort();
  const n = s.length;
  return n % 2 ? s[(n - 1) / 2] : (s[n / 2 - 1] + s[n / 2]) / 2;
}

async function rtt(client) {
  const [rounds = 30, perRound = 200, warm = 3] = args;
  const handle = await client.createVariableHandle(symbol);
  const probes = {
    readValue: () => client.readValue(symbol),
    readRawByPath: () => client.readRawByPath(symbol),
    readRawByHandle: () => client.readRawByHandle(handle),
  };
  const names = Object.keys(probes);
  const samples = Object.fromEntries(names.map((n) => [n, []]));
  const perRoundMedians = Object.fromEntries(names.map((n) => [n, []]));
  for (let r = 0; r < rounds + warm; r++) {
    for (let i = 0; i < names.length; i++) {
      const name = names[(i + r) % names.length];
      const fn = probes[name];
      const round = [];
      for (let k = 0; k < perRound; k++) {
        const t0 = now();
        await fn();
        round.push(now() - t0);
      }
      if (r >= warm) {
        samples[name].push(...round);
        perRoundMedians[name].push(median(round));
      }
    }
  }
  await client.deleteVariableHandle(handle);
  const out = { mode: 'rtt', symbol, rounds, per_round: perRound, warm_up_rounds: warm, median_us: {}, round_medians_us: perRoundMedians };
  for (const n of names) out.median_us[n] = median(samples[n]);
  return out;
}

async function load(client) {
  const [seconds = 5, periodMs = 1] = args;
  await client.readValue(symbol);                                       // symbol and type cached
  console.log(JSON.stringify({ ready: true }));
  await new Promise((resolve) => process.stdin.once('data', resolve));  // "go" from the bench
  process.stdin.pause();
  const period = periodMs * 1e3;
  const t0 = now();
  const tEnd = t0 + seconds * 1e6;
  let next = t0, reads = 0, errors = 0, last = t0, maxGap = 0;
  while (now() < tEnd) {
    try {
      await client.readValue(symbol);
      reads++;
    } catch (err) {
      errors++;
    }
    const t = now();
    maxGap = Math.max(maxGap, t - last);
    last = t;
    next += period;
    const pause = next - now();
    if (pause > 0) await sleep(Math.ceil(pause / 1e3));                   // Node's timers count whole ms
  }
  return { mode: 'load', symbol, reads, errors, seconds: (now() - t0) / 1e6, period_ms: periodMs, max_gap_ms: maxGap / 1e3 };
}

(async () => {
  const client = new Client({
    targetAmsNetId: '127.0.0.1.1.1', targetAdsPort: 851, routerAddress: '127.0.0.1', routerTcpPort: Number(port),
    autoReconnect: false, hideConsoleWarnings: true,
  });
  await client.connect();
  const out = mode === 'load' ? await load(client) : await rtt(client);
  await client.disconnect();
  console.log(JSON.stringify(out));
})().catch((err) => {
  console.log(JSON.stringify({ error: String(err && err.message), stack: String(err && err.stack) }));
  process.exitCode = 1;
});
