"""A small Debug Adapter Protocol client for tests: ``aioadept vplus dap`` as a real child process on stdio."""

from __future__ import annotations

import asyncio
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
VPLUS = ROOT / "vplus"
MODULES = [str(VPLUS / f) for f in ("rserver.V2", "rsskills.V2", "rsconfig.V2")]


def first_statement(path: Path, program: str) -> int:
    """The line of the first executable statement of ``program`` in ``path`` (after comments and declarations)."""
    lines = path.read_text(encoding="latin-1").splitlines()
    start = next(i for i, t in enumerate(lines) if t.strip().lower().startswith(f".program {program.lower()}("))
    for i in range(start + 1, len(lines)):
        t = lines[i].strip()
        if t and not t.startswith(";") and t.split()[0].upper() not in ("AUTO", "LOCAL", "GLOBAL"):
            return i + 1
    raise AssertionError(f"{program}: no statement")


class DapClient:
    def __init__(self, reader: asyncio.StreamReader, writer, proc: asyncio.subprocess.Process | None = None) -> None:
        self.proc = proc
        self.reader, self.writer = reader, writer
        self.seq = 0
        self.events: list[dict] = []
        self._waiters: dict[int, asyncio.Future] = {}
        self._event_cond = asyncio.Condition()
        self._reader = asyncio.ensure_future(self._read())

    @classmethod
    async def start(cls) -> DapClient:
        proc = await asyncio.create_subprocess_exec(sys.executable, "-m", "aioadept", "vplus", "dap",
                                                    stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE)
        return cls(proc.stdout, proc.stdin, proc)

    @classmethod
    async def connect(cls, port: int) -> DapClient:
        """A session over TCP (``aioadept sim --vplus --debug-port``)."""
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        return cls(reader, writer)

    async def _read(self) -> None:
        out = self.reader
        while True:
            header = await out.readline()
            if not header:
                break
            length = int(header.split(b":")[1])
            await out.readline()
            msg = json.loads(await out.readexactly(length))
            if msg["type"] == "response":
                fut = self._waiters.pop(msg["request_seq"], None)
                if fut is not None and not fut.done():
                    fut.set_result(msg)
            else:
                async with self._event_cond:
                    self.events.append(msg)
                    self._event_cond.notify_all()

    def send(self, command: str, arguments: dict | None = None) -> asyncio.Future:
        self.seq += 1
        msg = {"seq": self.seq, "type": "request", "command": command, "arguments": arguments or {}}
        body = json.dumps(msg).encode()
        self.writer.write(b"Content-Length: %d\r\n\r\n" % len(body) + body)
        fut = asyncio.get_running_loop().create_future()
        self._waiters[self.seq] = fut
        return fut

    async def request(self, command: str, arguments: dict | None = None, ok: bool = True) -> dict:
        resp = await asyncio.wait_for(self.send(command, arguments), 10)
        assert resp["success"] is ok, resp
        return resp.get("body") or {}

    async def event(self, name: str, after: int = 0, timeout: float = 10.0, **match) -> dict:
        """The first event ``name`` (from index ``after`` on) whose body has the ``match`` items."""
        def found():
            for e in self.events[after:]:
                if e["event"] == name and all(e["body"].get(k) == v for k, v in match.items()):
                    return e
            return None

        async with self._event_cond:
            await asyncio.wait_for(self._event_cond.wait_for(found), timeout)
            return found()

    def outputs(self) -> str:
        return "".join(e["body"]["output"] for e in self.events if e["event"] == "output")

    async def close(self) -> int | None:
        if self.proc is None:
            await asyncio.wait_for(self.send("disconnect"), 10)
            self.writer.close()
            self._reader.cancel()
            return None
        try:
            if self.proc.returncode is None:
                await asyncio.wait_for(self.send("disconnect", {"terminateDebuggee": True}), 10)
            return await asyncio.wait_for(self.proc.wait(), 10)
        finally:
            if self.proc.returncode is None:
                self.proc.kill()
                await self.proc.wait()
            self._reader.cancel()
