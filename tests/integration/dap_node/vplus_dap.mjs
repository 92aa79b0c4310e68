// Microsoft's DAP test client (DebugClient of @vscode/debugadapter-testsupport) against `aioadept vplus dap
// --listen`: the scenario of tests/integration/test_vplus_dap_node.py. Prints one JSON line: {"ok": true} or
// {"error": "..."}; argv: DAP_PORT JSON where JSON = {modules, rserver, l0, port, stopPort}.
import assert from 'node:assert/strict';
import net from 'node:net';
import testsupport from '@vscode/debugadapter-testsupport';

const { DebugClient } = testsupport;
const dapPort = Number(process.argv[2]);
const cfg = JSON.parse(process.argv[3]);
const dc = new DebugClient('unused', 'unused', 'vplus');

function line(socket) {
  return new Promise((resolve, reject) => {
    let buf = '';
    const onData = (d) => {
      buf += d.toString();
      const i = buf.indexOf('\n');
      if (i >= 0) { socket.off('data', onData); resolve(buf.slice(0, i + 1)); }
    };
    socket.on('data', onData);
    socket.once('error', reject);
  });
}

function stopped(reason) {
  return dc.waitForEvent('stopped').then((e) => { assert.equal(e.body.reason, reason); return e.body.threadId; });
}

async function main() {
  await dc.start(dapPort);
  const ready = new Promise((resolve) => dc.on('output', (e) => {
    if (e.body.output.startsWith(`READY host=127.0.0.1 port=${cfg.port} `)) resolve();
  }));
  const l0 = cfg.l0, l1 = l0 + 1, l2 = l0 + 2;
  const logs = [];
  dc.on('output', (e) => logs.push(e.body.output));
  await Promise.all([
    dc.waitForEvent('initialized').then(() => dc.setBreakpointsRequest({ source: { path: cfg.rserver },
      breakpoints: [{ line: l0 }, { line: l1, logMessage: 'id {$id}' }, { line: l2, condition: '$id == "00000002"' }] }))
      .then((r) => { assert.deepEqual(r.body.breakpoints.map((b) => [b.verified, b.line]), [[true, l0], [true, l1], [true, l2]]); })
      .then(() => dc.setExceptionBreakpointsRequest({ filters: ['all'] }))
      .then(() => dc.configurationDoneRequest()),
    dc.launch({ modules: cfg.modules, program: 'rs.main', portMap: { 1234: cfg.port, 1235: cfg.stopPort }, timeScale: 1 }),
  ]);
  await ready;
  const sock = net.createConnection(cfg.port, '127.0.0.1');
  await new Promise((resolve) => sock.once('connect', resolve));
  const hit = dc.assertStoppedLocation('breakpoint', { path: cfg.rserver, line: l0 });
  sock.write('00000001:here\r\n');
  const st = await hit;
  const frames = st.body.stackFrames;
  assert.match(frames[0].name, /^rs\.online\(/);
  assert.ok(frames.length >= 2 && frames.every((f) => f.source.path.endsWith('.V2')));
  const threads = (await dc.threadsRequest()).body.threads;
  const reader = threads.find((t) => /rs\.reader/.test(t.name));
  assert.equal(reader.id, 2);
  const scopes = (await dc.scopesRequest({ frameId: frames[0].id })).body.scopes;
  const auto = scopes.find((s) => s.name === 'AUTO');
  let vars = (await dc.variablesRequest({ variablesReference: auto.variablesReference })).body.variables;
  assert.equal(vars.find((v) => v.name === '$l').value, '"00000001:here"');
  // next: one V+ line (the logpoint there prints)
  const step = dc.assertStoppedLocation('step', { path: cfg.rserver, line: l1 });
  await dc.nextRequest({ threadId: 2 });
  const st2 = await step;
  assert.ok(logs.some((t) => t.startsWith('id "00000001"')));
  // the executor, task 0, is listed and its stack read while the reader is stopped
  assert.ok(threads.some((t) => t.id === 0));
  const ex = (await dc.stackTraceRequest({ threadId: 0 })).body.stackFrames;
  assert.match(ex[ex.length - 1].name, /^rs\.main\(/);
  // evaluate a location expression, set a variable
  const f0 = st2.body.stackFrames[0].id;
  const ev = (await dc.evaluateRequest({ expression: 'SHIFT(HERE BY 0, 0, 10)', frameId: f0, context: 'watch' })).body;
  assert.match(ev.result, /^TRANS\(/);
  const parts = (await dc.variablesRequest({ variablesReference: ev.variablesReference })).body.variables;
  assert.deepEqual(parts.map((p) => p.name), ['x', 'y', 'z', 'yaw', 'pitch', 'roll']);
  const scopes2 = (await dc.scopesRequest({ frameId: f0 })).body.scopes;
  const auto2 = scopes2.find((s) => s.name === 'AUTO').variablesReference;
  assert.equal((await dc.setVariableRequest({ variablesReference: auto2, name: 'n', value: '6*7' })).body.value, '42');
  // continue: the ack comes
  const ack = line(sock);
  await dc.continueRequest({ threadId: 2 });
  assert.match(await ack, /^00000001:done:/);
  // the plain breakpoint gone, the conditional one stops for ID 00000002 only
  await dc.setBreakpointsRequest({ source: { path: cfg.rserver }, breakpoints: [{ line: l2, condition: '$id == "00000002"' }] });
  const ack3 = line(sock);
  sock.write('00000003:here\r\n');
  assert.match(await ack3, /^00000003:done:/);
  const cond = dc.assertStoppedLocation('breakpoint', { path: cfg.rserver, line: l2 });
  sock.write('00000002:here\r\n');
  const st3 = await cond;
  // k (the slot) set out of range: the next line fails, an exception stop before REACTE
  const auto3 = (await dc.scopesRequest({ frameId: st3.body.stackFrames[0].id })).body.scopes
    .find((s) => s.name === 'AUTO').variablesReference;
  await dc.setVariableRequest({ variablesReference: auto3, name: 'k', value: '9999' });
  const exc = dc.waitForEvent('stopped');
  await dc.continueRequest({ threadId: 2 });
  const e = await exc;
  assert.equal(e.body.reason, 'exception');
  assert.match(e.body.text, /Undefined value/);
  sock.destroy();
  const terminated = dc.waitForEvent('terminated');
  await dc.disconnectRequest({ terminateDebuggee: true });
  await terminated.catch(() => {});
  dc.stopAdapter();
}

const timer = setTimeout(() => { console.log(JSON.stringify({ error: 'timed out' })); process.exit(1); }, 45000);
main().then(() => { clearTimeout(timer); console.log(JSON.stringify({ ok: true })); process.exit(0); },
  (err) => { clearTimeout(timer); console.log(JSON.stringify({ error: String(err && err.stack || err) })); process.exit(1); });
