"""``aioadept vplus dap`` as a real process, driven by a small DAP client: the shipped V+ server (vplus/) under the
debugger, a real TCP client talking to it. The issue's scenario, conditional breakpoints, logpoints, an exception
stop, evaluate and setVariable; and the safety of a breakpoint in the executor during a motion."""

from __future__ import annotations

import asyncio
import re

import pytest
from dapclient import MODULES, VPLUS, DapClient, first_statement

from aioadept.ports import free_port
from aioadept.testing.nodes import running_node

pytestmark = pytest.mark.timeout(60)
RSERVER = str(VPLUS / "rserver.V2")


async def launched(client: DapClient, breakpoints: dict[str, list[dict]], exceptions: list[str]) -> tuple[int, dict]:
    """initialize, launch vplus/ with rs.main, set breakpoints, configurationDone; (main port, bp responses)."""
    port, stop_port = free_port(), free_port()
    caps = await client.request("initialize", {"adapterID": "vplus", "linesStartAt1": True})
    assert caps["supportsConditionalBreakpoints"] and caps["supportsLogPoints"]
    launch = client.send("launch", {"modules": MODULES, "program": "rs.main", "portMap": {"1234": port,
                                    "1235": stop_port}, "timeScale": 1.0})
    await client.event("initialized")
    set_bps = {}
    for path, specs in breakpoints.items():
        set_bps[path] = await client.request("setBreakpoints", {"source": {"path": path}, "breakpoints": specs})
    await client.request("setExceptionBreakpoints", {"filters": exceptions})
    await client.request("configurationDone")
    assert (await asyncio.wait_for(launch, 10))["success"]
    await client.event("output", timeout=20, category="console", output=f"READY host=127.0.0.1 port={port} "
                                                                       f"vport=1234\n")
    return port, set_bps


async def stopped(client: DapClient, after: int, reason: str) -> tuple[int, list[dict]]:
    ev = await client.event("stopped", after, timeout=15, reason=reason)
    tid = ev["body"]["threadId"]
    return tid, (await client.request("stackTrace", {"threadId": tid}))["stackFrames"]


async def variables(client: DapClient, frame_id: int, scope: str = "AUTO") -> dict[str, dict]:
    scopes = (await client.request("scopes", {"frameId": frame_id}))["scopes"]
    ref = next(s["variablesReference"] for s in scopes if s["name"] == scope)
    return {v["name"]: v for v in (await client.request("variables", {"variablesReference": ref}))["variables"]}


async def test_the_v_plus_server_under_the_debugger_a_tcp_client_and_a_breakpoint_in_the_reader():
    l0 = first_statement(VPLUS / "rserver.V2", "rs.online")     # $id = $DECODE($l, ":", 0)
    l1, l2 = l0 + 1, l0 + 2                                      # CALL rs.isid(...); IF NOT ok THEN
    client = await DapClient.start()
    try:
        port, bps = await launched(client, {RSERVER: [
            {"line": l0}, {"line": l1, "logMessage": "id {$id} in slot {k}"},
            {"line": l2, "condition": '$id == "00000002"'}]}, ["untrapped"])
        assert [b["line"] for b in bps[RSERVER]["breakpoints"]] == [l0, l1, l2]
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        n = len(client.events)
        writer.write(b"00000001:here\r\n")
        await writer.drain()
        tid, frames = await stopped(client, n, "breakpoint")
        assert frames[0]["line"] == l0 and frames[0]["name"].startswith("rs.online(")
        assert frames[0]["source"]["path"] == RSERVER
        assert frames[1]["name"].startswith("rs.reader") or frames[1]["line"] != l0
        threads = {t["id"]: t["name"] for t in (await client.request("threads"))["threads"]}
        assert tid == 2 and "rs.reader" in threads[2] and 0 in threads       # the reader; the executor listed
        v = await variables(client, frames[0]["id"])
        assert v["$l"]["value"] == '"00000001:here"'
        # next: one V+ line; the logpoint on it prints instead of stopping
        n = len(client.events)
        await client.request("next", {"threadId": tid})
        _, frames = await stopped(client, n, "step")
        assert frames[0]["line"] == l1
        assert "id \"00000001\" in slot" in client.outputs()
        # the executor runs on while the reader is stopped: its stack is read where it waits
        ex = (await client.request("stackTrace", {"threadId": 0}))["stackFrames"]
        assert ex and all(f["source"]["path"].endswith(".V2") for f in ex) and ex[-1]["name"].startswith("rs.main")
        # evaluate a location expression in the frame, and its parts
        r = await client.request("evaluate", {"expression": "SHIFT(HERE BY 0, 0, 10)", "frameId": frames[0]["id"],
                                              "context": "watch"})
        assert r["result"].startswith("TRANS(") and r["variablesReference"] > 0
        parts = (await client.request("variables", {"variablesReference": r["variablesReference"]}))["variables"]
        assert [p["name"] for p in parts] == ["x", "y", "z", "yaw", "pitch", "roll"]
        bad = await client.request("evaluate", {"expression": "1 +", "frameId": frames[0]["id"]}, ok=False)
        assert bad == {} or "error" in bad
        # setVariable, read back by evaluate
        ref = next(s["variablesReference"] for s in (await client.request("scopes", {"frameId": frames[0]["id"]}))
                   ["scopes"] if s["name"] == "AUTO")
        assert (await client.request("setVariable", {"variablesReference": ref, "name": "n", "value": "6*7"})
                )["value"] == "42"
        assert (await client.request("evaluate", {"expression": "n", "frameId": frames[0]["id"]}))["result"] == "42"
        # continue: the TCP client gets its ack
        await client.request("continue", {"threadId": tid})
        ack = await asyncio.wait_for(reader.readline(), 10)
        assert ack.startswith(b"00000001:done"), ack
        # the plain breakpoint removed: the conditional one stops only for the second ID
        n = len(client.events)
        await client.request("setBreakpoints", {"source": {"path": RSERVER}, "breakpoints": [
            {"line": l2, "condition": '$id == "00000002"'}]})
        writer.write(b"00000003:here\r\n")
        assert (await asyncio.wait_for(reader.readline(), 10)).startswith(b"00000003:done")
        writer.write(b"00000002:here\r\n")
        tid, frames = await stopped(client, n, "breakpoint")
        assert frames[0]["line"] == l2
        # an exception stop: k (the reader's slot, by reference) set out of range makes the next line fail
        await client.request("setExceptionBreakpoints", {"filters": ["all"]})
        v = await variables(client, frames[0]["id"])
        ref = next(s["variablesReference"] for s in (await client.request("scopes", {"frameId": frames[0]["id"]}))
                   ["scopes"] if s["name"] == "AUTO")
        await client.request("setVariable", {"variablesReference": ref, "name": "k", "value": "9999"})
        n = len(client.events)
        await client.request("continue", {"threadId": tid})
        ev = await client.event("stopped", n, timeout=10, reason="exception")
        assert "Undefined value" in ev["body"]["text"] and ev["body"]["threadId"] == 2
        writer.close()
    finally:
        code = await client.close()
    assert code == 0
    assert any(e["event"] == "terminated" for e in client.events)


async def test_attached_to_a_running_sim_a_breakpoint_in_the_executor_during_a_motion_leaves_stop_to_the_reader(
        tmp_path):
    """``aioadept sim --vplus --debug-port``: a DAP session attaches; a breakpoint in the executor right after a
    skill's MOVE stops it (the arm is braked); the reader serves the stop meanwhile (its watchdog restarts the
    executor, which acks); the arm rests; the session's end leaves the server serving."""
    text = (VPLUS / "rserver.V2").read_text(encoding="latin-1").splitlines()
    after_skill = next(i + 3 for i, t in enumerate(text) if "CALLS $p(rs.xa[])" in t)    # after CALLS ... END
    assert "IF rs.stopin <> rs.stopout THEN" in text[after_skill - 1]
    debug_port = free_port()
    async with running_node("sim", "--vplus", *MODULES, "--run", "rs.main", "--map-port", "1234=0",
                            "--map-port", "1235=0", "--state-endpoint", "none", "--debug-port", str(debug_port),
                            log_path=tmp_path / "sim.log") as node:
        port = int(node.ready["port"])
        client = await DapClient.connect(debug_port)
        await client.request("initialize", {"adapterID": "vplus"})
        await client.request("attach", {})
        await client.event("initialized")
        bps = await client.request("setBreakpoints", {"source": {"path": RSERVER},
                                                      "breakpoints": [{"line": after_skill}]})
        assert bps["breakpoints"][0]["verified"]
        await client.request("configurationDone")
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        writer.write(b"00000001:here\r\n")
        start = await asyncio.wait_for(reader.readline(), 10)
        writer.write(b"00000002:move_rel_joints:0,0,0,0,0,90\r\n")
        tid, frames = await stopped(client, 0, "breakpoint")
        assert tid == 0 and frames[0]["line"] == after_skill and frames[0]["name"].startswith("rs.run1(")
        writer.write(b"00000003:stop\r\n")
        # the reader serves the stop: it brakes, and its watchdog (rs.unstick, rs.stwd) restarts the executor,
        # held at the breakpoint, which acks the move aborted and the stop done
        acks = [await asyncio.wait_for(reader.readline(), 10) for _ in range(2)]
        assert acks[0].startswith(b"00000002:aborted:") and acks[1].startswith(b"00000003:done:"), acks
        assert "executor restarted" in node.tail()
        poses = []
        for i in (4, 5):
            writer.write(b"0000000%d:here\r\n" % i)
            poses.append((await asyncio.wait_for(reader.readline(), 10)).split(b":", 3)[3])
            await asyncio.sleep(0.3)
        # the arm came to rest where the breakpoint braked it, right after the move began: the 90 degrees of
        # J6 (the pose's roll) never went on
        assert poses[0] == poses[1] == acks[1].split(b":", 3)[3]
        roll = [float(p.split(b",")[5]) for p in (start.split(b":", 3)[3], poses[0])]
        assert abs(roll[1] - roll[0]) < 5.0, roll
        await client.close()                  # detach: the breakpoint goes, the server serves on
        writer.write(b"00000006:here\r\n")
        assert (await asyncio.wait_for(reader.readline(), 10)).startswith(b"00000006:done")
        # the same port serves the V+ monitor (aioadept vplus monitor --connect): lines in, replies out
        mr, mw = await asyncio.open_connection("127.0.0.1", debug_port)
        mw.write(b"STATUS\nLISTR rs.port\nLOAD x.V2\nEXIT\n")
        reply = (await asyncio.wait_for(mr.read(), 10)).decode()
        assert re.search(r"2\s+running\s+rs\.reader", reply) and "rs.port = 1234" in reply, reply
        assert "LOAD: not over --connect" in reply
        mw.close()
        writer.close()
