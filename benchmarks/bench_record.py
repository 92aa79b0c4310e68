"""What the Rerun recording (docs/record.md) costs the focus loop, with its baseline measured in the same run.

The focus loop (:func:`aioadept.apps.paper.ufloop`, no init move) runs against the in-process simulated controller
(real TCP on 127.0.0.1, real time, its 100 Hz state stream on) and a vision Responder over real ZeroMQ that answers
with a sharpness series and the ``camera``/``frame_seq`` of a 1024 x 768 frame saved as PNG, as the vision node
does with ``--save-frames``. Runs alternate between ``off`` (the timing Recorder only, as before) and ``on`` (plus
a :class:`aioadept.record.RunRecording`: run.rrd, the state stream followed, each frame read, downsampled and
logged; and the :class:`aioadept.record.mcapfile.StateTap` that keeps the state stream for run.mcap, which is then
written after the run, as the applications do; its writing time is reported, not judged). The cycle is one focus
step: mark ``iteration`` to the next.

Verdicts:

1. median cycle with recording / without: goal <= 1.02 (the issue's 2 %). On a loaded 2-core machine the
   per-round ratio wanders by more than that; the median of the per-round ratios is quoted.
2. loop time of the hooks per cycle (measured directly: the observer calls of one cycle, timed on the loop) over
   the median cycle: goal <= 0.02. This is the part that cannot hide in the noise of 1.
3. the longest single hook call (a frame's response included): goal <= 1 ms (nothing blocks the loop).

Usage: ``python benchmarks/bench_record.py [--rounds 6] [--steps 8] [--quick]``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import platform
import statistics
import sys
import tempfile
from itertools import pairwise
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from verdicts import verdict  # noqa: E402

ANY = "tcp://127.0.0.1:0"


class Marks:
    def __init__(self) -> None:
        self.t: list[float] = []

    def mark(self, name: str, value=None, *, t_s=None) -> None:  # noqa: ANN001
        if name == "iteration":
            self.t.append(asyncio.get_running_loop().time())


class Timed:
    """Wraps an observer and times each hook call on the loop (perf_counter)."""

    def __init__(self, inner) -> None:  # noqa: ANN001
        self.inner = inner
        self.calls: list[float] = []

    def _timed(self, name: str, arg) -> None:  # noqa: ANN001
        t0 = time.perf_counter()
        getattr(self.inner, name)(arg)
        self.calls.append(time.perf_counter() - t0)

    def on_send(self, m) -> None:  # noqa: ANN001
        self._timed("on_send", m)

    def on_ack(self, m) -> None:  # noqa: ANN001
        self._timed("on_ack", m)

    def on_request(self, m) -> None:  # noqa: ANN001
        self._timed("on_request", m)

    def on_response(self, m) -> None:  # noqa: ANN001
        self._timed("on_response", m)


async def one_run(sim, frames: Path, steps: int, record: bool, out: Path, speed: int) -> dict:  # noqa: ANN001
    from aioadept.apps.paper import ufloop
    from aioadept.bus import Communicator, Responder
    from aioadept.runs.capture import Recorder
    from aioadept.client import RobotClient
    from aioadept.record.hook import MarkTee
    from aioadept.record.live import RunRecording
    from aioadept.record.mcapfile import StateTap, write_run_mcap

    series = [float(i) for i in range(1, steps)] + [0.5]
    n = {"i": 0}

    def handler(event_type, rid, attrs):  # noqa: ANN001, ANN202
        i = n["i"]
        n["i"] += 1
        return {"sharpness": series[min(i, len(series) - 1)], "frame_t": time.time(), "camera": "virtual",
                "frame_seq": 1, "frame_age_ms": 1.0}

    recorder = Recorder()
    marks = Marks()
    rrd = None
    tap = None
    timed: Timed | None = None
    async with contextlib.AsyncExitStack() as stack:
        responder = await stack.enter_async_context(Responder(ANY, ANY, handler))
        observers: list = [recorder]
        if record:
            rrd = RunRecording(out / "run.rrd", state_endpoint=sim.state_endpoint, frames_dir=frames,
                               clock_ref=recorder, short_switch_interval=True).start()  # as the CLIs record
            timed = Timed(rrd)
            observers.append(timed)
            tap = StateTap(sim.state_endpoint).start()  # run.mcap's state messages, as run_focus_once keeps them
        rc = await stack.enter_async_context(RobotClient(sim.host, sim.port, observers=observers))
        comm = await stack.enter_async_context(
            Communicator(responder.actual_request_endpoint, responder.actual_response_endpoint, timeout_s=5, bind=False,
                         observers=observers))
        tee = MarkTee(recorder, marks, rrd)
        t_mark: list[float] = []
        if timed is not None:  # marks go through the recording too: time them with the hooks
            orig = rrd.mark

            def timed_mark(*a, **k):  # noqa: ANN002, ANN003, ANN202
                t0 = time.perf_counter()
                orig(*a, **k)
                t_mark.append(time.perf_counter() - t0)

            rrd.mark = timed_mark  # type: ignore[method-assign]
        await ufloop(rc, comm, 2.0, speed, max_steps=steps + 2, do_init_move=False, recorder=tee)
        # back to where this run started, so every run covers the same path
        from aioadept.commands import MoveToolZ, SetSpeed

        await rc.cmdexec(SetSpeed(100), MoveToolZ(-2.0 * (steps - 1)))
    mcap_s = None
    states_kept = 0
    if rrd is not None:
        await rrd.aclose()
    if tap is not None:
        payloads = await tap.stop()
        states_kept = len(payloads)
        t0 = time.perf_counter()
        why = await asyncio.to_thread(write_run_mcap, recorder.snapshot(), out / "run.mcap", frames_dir=frames,
                                      state=payloads)
        mcap_s = time.perf_counter() - t0
        assert why is None, why
    cycles = [b - a for a, b in pairwise(marks.t)]
    hooks = (timed.calls if timed else []) + t_mark
    return {"cycles_s": cycles, "hook_s": hooks, "frames": rrd.logger.counts.get("frame", 0) if rrd else 0,
            "states": rrd.logger.counts.get("state", 0) if rrd else 0, "mcap_write_s": mcap_s,
            "mcap_states": states_kept}


async def main_async(args: argparse.Namespace) -> dict:
    import cv2
    import numpy as np

    from aioadept.apps.paper import init_move
    from aioadept.client import RobotClient
    from aioadept.testing.sim import running_sim

    tmp = Path(tempfile.mkdtemp(prefix="bench-record-"))
    frames = tmp / "frames"
    frames.mkdir()
    rng = np.random.default_rng(0)
    cv2.imwrite(str(frames / "virtual_000001.png"), rng.integers(0, 255, (768, 1024), dtype=np.uint8))
    per_round: list[float] = []
    on_cycles: list[float] = []
    off_cycles: list[float] = []
    hooks: list[float] = []
    hook_per_cycle: list[float] = []
    counts = {"frames": 0, "states": 0, "mcap_states": 0}
    mcap_write: list[float] = []
    async with running_sim(state_endpoint=ANY, time_scale=1.0) as sim:
        async with RobotClient(sim.host, sim.port) as rc:
            await init_move(rc)
        for r in range(args.rounds):
            order = (False, True) if r % 2 == 0 else (True, False)
            med = {}
            for record in order:
                res = await one_run(sim, frames, args.steps, record, tmp / f"r{r}-{int(record)}", args.speed)
                med[record] = statistics.median(res["cycles_s"])
                (on_cycles if record else off_cycles).extend(res["cycles_s"])
                if record:
                    hooks.extend(res["hook_s"])
                    hook_per_cycle.append(sum(res["hook_s"]) / max(1, len(res["cycles_s"]) + 1))
                    counts["frames"] += res["frames"]
                    counts["states"] += res["states"]
                    counts["mcap_states"] += res["mcap_states"]
                    mcap_write.append(res["mcap_write_s"])
            per_round.append(med[True] / med[False])
    ratio = statistics.median(per_round)
    off_med = statistics.median(off_cycles)
    on_med = statistics.median(on_cycles)
    hook_cycle = statistics.median(hook_per_cycle)
    hook_max = max(hooks) if hooks else float("nan")
    return {
        "benchmark": "record",
        "python": sys.version.split()[0], "platform": platform.platform(), "cpus": os.cpu_count(),
        "params": {"rounds": args.rounds, "steps": args.steps, "speed": args.speed, "frame": "1024x768 PNG"},
        "cycle_ms": {"off_median": off_med * 1e3, "on_median": on_med * 1e3,
                     "per_round_ratio": per_round},
        "hooks_us": {"per_cycle_median": hook_cycle * 1e6, "max": hook_max * 1e6,
                     "p50": statistics.median(hooks) * 1e6 if hooks else None, "calls": len(hooks)},
        "logged": counts,
        "mcap_write_ms": {"median": statistics.median(mcap_write) * 1e3, "max": max(mcap_write) * 1e3},
        "verdicts": [
            verdict("focus cycle median, recording on vs off", on_med * 1e3, off_med * 1e3, unit="ms", ratio=ratio,
                    goal="ratio <= 1.02", passed=ratio <= 1.02),
            verdict("recording hooks' loop time per cycle / median cycle", hook_cycle * 1e3, off_med * 1e3,
                    unit="ms", goal="ratio <= 0.02", passed=hook_cycle / off_med <= 0.02),
            verdict("longest recording hook call (a frame's response included)", hook_max * 1e3, 1.0, unit="ms",
                    goal="ratio <= 1 (1 ms)", passed=hook_max <= 1e-3),
        ],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=6)
    p.add_argument("--steps", type=int, default=8)
    p.add_argument("--speed", type=int, default=25)
    p.add_argument("--quick", action="store_true", help="2 rounds of 4 steps (smoke run)")
    args = p.parse_args()
    if args.quick:
        args.rounds, args.steps = 2, 4
    print(json.dumps(asyncio.run(main_async(args)), indent=2))


if __name__ == "__main__":
    main()
