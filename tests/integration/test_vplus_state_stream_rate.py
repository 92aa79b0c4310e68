"""The V+ server's state stream (vplus/rsstate.V2, ``rs.stream = TRUE``) keeps its configured rate: after a pause
of the whole controller (50 ms: a busy moment, made here by SIGSTOP/SIGCONT of the real ``aioadept sim --vplus``
process) it comes back to 100 samples/s, after each of several such pauses, instead of one sample per 16 ms cycle (docs/vplus.md, "The state
stream"). The samples are read straight off the stream's TCP port and timed on the server's own clock (``t=``)."""

from __future__ import annotations

import asyncio
import os
import signal
import statistics
from pathlib import Path

import pytest

from aioadept.testing.nodes import running_node
from aioadept.ports import free_port

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
RATE = 100
PAUSES = 8
"""Pauses in a row: where a pause ends within the 16 ms cycle decides whether the old arithmetic got stuck at 63/s
(about one time in three), so several pauses make the test see it."""


def stream_files(tmp_path: Path) -> list[str]:
    cfg = (VPLUS / "rsconfig.V2").read_text()
    assert "rs.stream = FALSE" in cfg and "rs.strate = 100" in cfg
    (tmp_path / "rsconfig.V2").write_text(cfg.replace("rs.stream = FALSE", "rs.stream = TRUE"))
    return [str(VPLUS / "rserver.V2"), str(VPLUS / "rsskills.V2"), str(tmp_path / "rsconfig.V2"),
            str(VPLUS / "rsstate.V2")]


async def sample_times(reader: asyncio.StreamReader, seconds: float) -> list[float]:
    """The server times (``t=``) of the samples that arrive in the next ``seconds``."""
    out: list[float] = []
    loop = asyncio.get_running_loop()
    end = loop.time() + seconds
    while (left := end - loop.time()) > 0:
        try:
            line = await asyncio.wait_for(reader.readline(), left)
        except TimeoutError:
            break
        assert line, "the state stream closed"
        fields = dict(f.split("=", 1) for f in line.decode().split()[1:] if "=" in f)
        out.append(float(fields["t"]))
    return out


def period_ms(ts: list[float]) -> float:
    """The median time between two samples, on the server's clock (ms): a moment of load on this shared machine
    drops a few samples, a stream stuck at one sample per cycle has every period 16 ms."""
    assert len(ts) > 10, ts
    return 1000 * statistics.median(b - a for a, b in zip(ts, ts[1:], strict=False))


@pytest.mark.timeout(60)
async def test_the_v_plus_state_stream_comes_back_to_its_rate_after_a_50_ms_pause(tmp_path):
    sport = free_port()
    async with running_node("sim", "--vplus", *stream_files(tmp_path), "--run", "rs.main",
                            "--map-port", "1234=0", "--map-port", "1235=0", "--map-port", f"1236={sport}",
                            "--state-endpoint", "none", log_path=tmp_path / "sim.log", ready_timeout_s=60) as sim:
        reader, writer = await asyncio.open_connection("127.0.0.1", sport)
        try:
            await sample_times(reader, 0.5)                    # connected, the stream runs
            before = period_ms(await sample_times(reader, 1.5))
            pid = sim.proc.pid
            afters = []
            for _ in range(PAUSES):
                os.kill(pid, signal.SIGSTOP)                    # the whole controller stops for 50 ms
                try:
                    await asyncio.sleep(0.05)
                finally:
                    os.kill(pid, signal.SIGCONT)
                await sample_times(reader, 0.2)                 # what was missed is skipped, not sent in a burst
                afters.append(period_ms(await sample_times(reader, 0.6)))
        finally:
            writer.close()
    print(f"sample period before {before:.1f} ms, after each pause {[round(a, 1) for a in afters]} ms")
    assert before == pytest.approx(1000 / RATE, abs=1.5), before
    assert all(a == pytest.approx(1000 / RATE, abs=1.5) for a in afters), (before, afters)
