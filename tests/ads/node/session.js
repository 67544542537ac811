// One ads-client session in its default mode against a served distctrl machine (issue 14).
//
//   node session.js <ads port> <axis index> [<AMS NetId>]
//
// Every step is recorded, never thrown: the last line on stdout is one JSON object
// {step: {ok: true, value} | {ok: false, error, code}}; tests/ads/test_ads_client.py judges it.
'use strict';
const { Client } = require('ads-client');

const [port, axis, netId = '127.0.0.1.1.1'] = process.argv.slice(2);
const unit = `gpAx[${axis}].lr_mc_control.distance_control`;
const steps = {};

async function step(name, fn) {
  try {
    steps[name] = { ok: true, value: await fn() };
  } catch (err) {
    let cause = err;
    while (cause && !cause.adsError && cause.parent) cause = cause.parent;   // ads-client wraps errors
    const ads = (cause && cause.adsError) || err.adsError;
    steps[name] = { ok: false, error: String(err.message), code: ads ? ads.errorCode : null };
  }
  return steps[name];
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function until(fn, timeoutMs = 3000) {
  const end = Date.now() + timeoutMs;
  for (;;) {
    const v = await fn();
    if (v || Date.now() > end) return v;
    await sleep(5);
  }
}

// hand a command to the CNC as a PLC program does: command_w, enable_w, then the semaphore; the CNC
// clears the semaphore in the cycle it takes the command; then the state it leads to (`expect`), read
// until it is reached (bounded: the cycle thread may run late on a busy machine)
async function command(client, transition, position, expect) {
  await client.writeValue(`${unit}.command_w`, { transition, position });
  await client.writeValue(`${unit}.enable_w`, true);
  await client.writeValue(`${unit}.command_semaphore_rw`, true);
  const taken = await until(async () => !(await client.readValue(`${unit}.command_semaphore_rw`)).value);
  if (!taken) throw new Error('the CNC did not take the command within 3 s');
  let state;
  await until(async () => {
    state = (await client.readValue(`${unit}.state_r`)).value;
    return state.actual_state === expect;
  });
  return state;
}

(async () => {
  const client = new Client({
    targetAmsNetId: netId, targetAdsPort: 851, routerAddress: '127.0.0.1', routerTcpPort: Number(port),
    autoReconnect: false,
  });
  const connected = await step('connect', async () => {
    const r = await client.connect();
    return { connected: r.connected, targetAdsPort: r.targetAdsPort, localAdsPort: r.localAdsPort };
  });
  if (connected.ok) {
    await step('system_state', async () => (await client.readTcSystemExtendedState()).adsStateStr);
    await step('device_info', async () => (await client.readDeviceInfo()).deviceName);
    // the PLC runtime state arrives by the 0xF100 notification ads-client subscribed to on connect
    await step('runtime_state', async () => (await until(async () => client.metaData.plcRuntimeState)).adsStateStr);
    await step('symbol_version', async () => client.metaData.plcSymbolVersion);
    await step('read_bool', async () => (await client.readValue(`${unit}.enable_w`)).value);
    await step('read_struct', async () => (await client.readValue(`${unit}.state_r`)).value);
    await step('read_dint', async () => (await client.readValue(`${unit}.state_r.actual_position`)).value);
    await step('read_channel_status', async () => (await client.readValue('gpCh[1].bahn_state')).value);
    await step('data_type', async () => {
      const t = await client.getDataType('HLI_DISTANCE_CONTROL_STATE');
      return { size: t.size, members: t.subItems.map((i) => [i.name, i.type, i.offset]) };
    });
    const vars = await step('variables', async () => Object.values(await client.getSymbols())
      .map((s) => s.name).filter((n) => n.startsWith('V.E.')));
    if (vars.ok && vars.value.length) {
      const name = vars.value[0];
      await step('write_lreal', async () => {
        await client.writeValue(name, 2.5);
        return (await client.readValue(name)).value;
      });
    }
    await step('handle', async () => {
      const h = await client.createVariableHandle(`${unit}.state_r.actual_state`);
      const raw = await client.readRawByHandle(h);
      await client.deleteVariableHandle(h);
      return { size: h.size, dataType: h.dataType, bytes: raw.length };
    });
    await step('on', async () => command(client, 1, 400000, 1));        // ON, SET_POS 40 mm
    const seen = [];
    await step('subscribe', async () => {
      const sub = await client.subscribeValue(`${unit}.state_r.actual_offset`,
        (data) => seen.push(data.value), 10);
      await sleep(300);
      await sub.unsubscribe();
      return seen.length;
    });
    await step('subscribe_struct', async () => {
      const got = [];
      const sub = await client.subscribeValue(`${unit}.state_r`, (data) => got.push(data.value), 10);
      await until(async () => got.length >= 1);     // at least one sample (bounded, 3 s)
      await sub.unsubscribe();
      return { count: got.length, fields: got.length ? Object.keys(got[0]) : [] };
    });
    await step('sum_read', async () => {
      const syms = await Promise.all([`${unit}.state_r.actual_state`, `${unit}.enable_w`]
        .map((p) => client.getSymbol(p)));
      const res = await client.readRawMulti(syms.map((s) => ({
        indexGroup: s.indexGroup, indexOffset: s.indexOffset, size: s.size })));
      return res.map((r) => (r.success ? [...r.value] : r.errorCode));
    });
    await step('sum_handles', async () => {
      const res = await client.createVariableHandleMulti([`${unit}.state_r.actual_state`, 'gpAx[99].nope']);
      const ok = res.filter((r) => r.success).map((r) => r.handle);
      await client.deleteVariableHandleMulti(ok);
      return res.map((r) => (r.success ? 0 : r.errorCode));
    });
    await step('off', async () => command(client, 0, 0, 0));              // OFF
    await step('unknown_symbol', async () => client.readValue('gpAx[99].nope'));
    await step('read_only', async () => client.writeValue(`${unit}.state_r.actual_state`, 3));
    await step('unknown_type', async () => client.getDataType('NO_SUCH_TYPE'));
    await step('unknown_type_raw', async () => client.readWriteRaw(0xF011, 0, 0xFFFFFFFF, Buffer.from('NO_SUCH_TYPE\0')));
    await step('stop_plc', async () => {
      await client.stopPlc();
      const stopped = await until(async () => client.metaData.plcRuntimeState.adsStateStr === 'Stop');
      await client.startPlc();
      const running = await until(async () => client.metaData.plcRuntimeState.adsStateStr === 'Run');
      return { stopped, running, connected: client.connection.connected };
    });
    await step('cnc_port', async () => {          // the GEO task's CNC objects: a second client, default mode
      const cnc = new Client({ targetAmsNetId: netId, targetAdsPort: 551, routerAddress: '127.0.0.1',
        routerTcpPort: Number(port), autoReconnect: false });
      await cnc.connect();
      const kp = (await cnc.readRaw(0x120300, (Number(axis) << 16) | 0x3106, 8)).readDoubleLE(0);
      await cnc.disconnect();
      return kp;
    });
    await step('disconnect', async () => {
      await client.disconnect();
      return client.connection.connected;
    });
  }
  process.stdout.write(JSON.stringify(steps) + '\n');
  process.exit(0);
})();
