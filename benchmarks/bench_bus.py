"""Request -> response latency through Communicator + Responder (no-op handler) vs raw pyzmq PUB/SUB ping-pong.

Both are measured in the same run with the same topology: the server side (Responder, or a raw asyncio echo) runs
in a child process that binds a SUB for requests and a PUB for responses on 127.0.0.1 port 0 and reports its real
endpoints through a pipe (a handshake, no sleep); the client side connects a PUB and a SUB from an asyncio loop.
The raw ping-pong sends a pre-encoded request Event of the same size and awaits the echoed bytes, so the ratio is
what the Communicator/Responder machinery costs: Protobuf encode/decode, ids, futures, the reader task, caching.

The same Communicator + Responder also run over Eclipse Zenoh (the ``[zenoh]`` extra): the child
process is the Zenoh router, listening on a free 127.0.0.1 port, and this process connects to it as a client
(multicast scouting and gossip off), with the same no-op handler and payloads. Beside it, the floor of any asyncio
code on Zenoh: a raw Zenoh ping-pong between the same two processes with the same session options, each side handing
the sample from Zenoh's callback thread to its event loop through an eventfd the loop watches (the hop the transport
cannot avoid: Zenoh has no file descriptor to poll; the leanest hop known, the one ZenohSocket uses) and nothing
else. And the same again with ``Communicator(queries=True)``: each request a Zenoh query, each answer its reply
(docs/bus.md, "Requests: publications or Zenoh queries"), shown without a goal. Rounds alternate raw / ZeroMQ / raw
Zenoh / Zenoh / Zenoh queries.

The ZeroMQ / raw Zenoh / Zenoh / Zenoh queries runs are measured twice in each round: as above, wherever the scheduler puts the
threads, and pinned, the requester's process on CPU 0 and the node's on CPU 1 (both started pinned, so every thread
ZeroMQ or Zenoh starts stays with its process), as Zenoh's own latency benchmarks run z_ping and z_pong under
taskset. Why both: a Zenoh process hands each message through three threads (Zenoh's network thread, its Python
callback thread, the event loop), a ZeroMQ one through two; on this 2-core VM the scheduler keeps moving them between
the cores, and each wake-up that crosses cores costs tens of microseconds, so unpinned Zenoh rounds come out bimodal
(per round 0.7-3.1 x ZeroMQ in one run). Pinned, both transports are measured without that noise: the goal is
judged there; the unpinned ratio is printed beside it, without a goal (docs/bus.md, Cost).

Prints one JSON object. Usage: ``python benchmarks/bench_bus.py [--n 2000] [--warmup 300] [--rounds 5]``.
Targets: ours p50 <= 1.3 x raw p50 (unpinned); ours over Zenoh p50 <= 1.3 x ours over ZeroMQ p50 (pinned
where the machine has two CPUs to pin to, else unpinned). Each Zenoh verdict's ratio is the median of the rounds'
ratios (each round's Zenoh p50 over the same round's ZeroMQ p50, measured one after the other), as bench_client and
bench_multi_cell judge theirs: on this VM a whole process now and then runs about twice as slow for a run (docs/bus.md,
Cost), and a pooled p50 takes that round in whole whereas the median of five paired rounds sets it aside. The pooled
ratio is in the JSON beside it. The raw Zenoh floor over ours on ZeroMQ is printed beside each: when the floor alone
is near 1.3, the goal is out of reach of any Python asyncio layer, whatever the bus does.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing as mp
import os
import platform
import statistics
import sys
import time

import zmq

from verdicts import verdict
import zmq.asyncio

from aioadept.bus.communicator import Communicator
from aioadept.bus.responder import Responder
from aioadept.bus.messages import encode_event
from aioadept.errors import RequestTimeout

ANY = "tcp://127.0.0.1:*"


# ------------------------------------------------------------------------------------------------ server processes

def _raw_server(conn) -> None:
    async def main() -> None:
        ctx = zmq.asyncio.Context()
        sub = ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.bind(ANY)
        pub = ctx.socket(zmq.PUB)
        pub.bind(ANY)
        conn.send((sub.getsockopt_string(zmq.LAST_ENDPOINT), pub.getsockopt_string(zmq.LAST_ENDPOINT)))
        try:
            while True:
                msg = await sub.recv()
                await pub.send(msg)
                if msg == b"STOP":
                    break
        finally:
            sub.close(0)
            pub.close(0)
            ctx.term()

    asyncio.run(main())


def _responder_server(conn) -> None:
    async def main() -> None:
        stop = asyncio.Event()

        def handler(event_type, rid, attrs):
            if event_type == "STOP":
                stop.set()
            return None  # no-op: empty attributes

        async with Responder(ANY, ANY, handler) as node:
            conn.send((node.peer_request_endpoint, node.peer_response_endpoint))
            await stop.wait()
            await asyncio.sleep(0.05)  # shutdown grace so the STOP answer can leave; not on the measured path

    asyncio.run(main())


def _zenoh_responder_server(conn, router: str, key: str) -> None:
    from aioadept.bus import zenoh as zb

    zb.configure(zb.ZenohOptions.router(router))

    async def main() -> None:
        stop = asyncio.Event()

        def handler(event_type, rid, attrs):
            if event_type == "STOP":
                stop.set()
            return None

        async with Responder(f"zenoh:{key}/request", f"zenoh:{key}/response", handler) as node:
            conn.send((node.peer_request_endpoint, node.peer_response_endpoint))
            await stop.wait()
            await asyncio.sleep(0.05)

    try:
        asyncio.run(main())
    finally:
        zb.close_session()


class _EventfdHop:
    """The leanest hand-over from Zenoh's callback thread to an event loop that we know: append to a deque and write
    an eventfd the loop watches (what ZenohSocket does); ``on_message`` then runs on the loop's thread."""

    def __init__(self, loop: asyncio.AbstractEventLoop, on_message) -> None:
        import collections

        self._queue: collections.deque[bytes] = collections.deque()
        self._efd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)
        self._on_message = on_message
        self._loop = loop
        loop.add_reader(self._efd, self._readable)

    def callback(self, sample) -> None:  # Zenoh's thread
        self._queue.append(sample.payload.to_bytes())
        os.eventfd_write(self._efd, 1)

    def _readable(self) -> None:
        try:
            os.eventfd_read(self._efd)
        except BlockingIOError:
            pass
        while self._queue:
            self._on_message(self._queue.popleft())

    def close(self) -> None:
        self._loop.remove_reader(self._efd)
        os.close(self._efd)


def _raw_zenoh_server(conn, router: str, key: str) -> None:
    from aioadept.bus import zenoh as zb

    zenoh = zb._zenoh()
    sess = zenoh.open(zb.ZenohOptions.router(router).config())

    async def main() -> None:
        loop = asyncio.get_running_loop()
        stop = loop.create_future()
        pub = sess.declare_publisher(f"{key}/response", express=True)

        def echo(msg: bytes) -> None:
            pub.put(msg)
            if msg == b"STOP" and not stop.done():
                stop.set_result(None)

        hop = _EventfdHop(loop, echo)
        sub = sess.declare_subscriber(f"{key}/request", zenoh.handlers.Callback(hop.callback, indirect=True))
        conn.send(("", ""))
        try:
            await stop
            await asyncio.sleep(0.05)
        finally:
            sub.undeclare()
            pub.undeclare()
            hop.close()

    try:
        asyncio.run(main())
    finally:
        sess.close()


async def _raw_zenoh_client(sess, key: str, n: int, warmup: int) -> list[float]:
    zenoh = sys.modules["zenoh"]
    loop = asyncio.get_running_loop()
    waiting: list[asyncio.Future] = []

    def _answer(msg: bytes) -> None:
        if waiting and not waiting[0].done():
            waiting.pop(0).set_result(msg)

    hop = _EventfdHop(loop, _answer)
    pub = sess.declare_publisher(f"{key}/request", express=True)
    sub = sess.declare_subscriber(f"{key}/response", zenoh.handlers.Callback(hop.callback, indirect=True))
    payload = encode_event("VisionRequest", "0123abcd", {"t_request": time.time()})
    try:
        while True:  # join: ping until an answer comes back
            fut = loop.create_future()
            waiting[:] = [fut]
            pub.put(payload)
            try:
                await asyncio.wait_for(fut, 0.05)
                break
            except asyncio.TimeoutError:
                continue
        await asyncio.sleep(0.05)  # let duplicate answers of the join drain
        samples = []
        for i in range(warmup + n):
            t0 = loop.time()
            fut = loop.create_future()
            waiting[:] = [fut]
            pub.put(payload)
            await fut
            if i >= warmup:
                samples.append(loop.time() - t0)
        fut = loop.create_future()
        waiting[:] = [fut]
        pub.put(b"STOP")
        try:
            await asyncio.wait_for(fut, 2.0)
        except asyncio.TimeoutError:
            pass
        return samples
    finally:
        sub.undeclare()
        pub.undeclare()
        hop.close()


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _pinned(cpus, target, *args) -> None:
    """Run ``target(*args)`` in this process on ``cpus`` only (None: wherever the scheduler likes). Set before
    anything starts a thread, so ZeroMQ's and Zenoh's threads inherit it."""
    if cpus is not None:
        os.sched_setaffinity(0, cpus)
    target(*args)


def _start(target, *args: str, cpus: set[int] | None = None) -> tuple[mp.Process, str, str]:
    parent, child = mp.Pipe()
    proc = mp.get_context("spawn").Process(target=_pinned, args=(cpus, target, child, *args), daemon=True)
    proc.start()
    if not parent.poll(20):
        proc.kill()
        raise RuntimeError(f"{target.__name__} did not report its endpoints")
    req, resp = parent.recv()
    return proc, req, resp


# ------------------------------------------------------------------------------------------------ clients

async def _raw_client(req_ep: str, resp_ep: str, n: int, warmup: int) -> list[float]:
    ctx = zmq.asyncio.Context()
    pub = ctx.socket(zmq.PUB)
    pub.connect(req_ep)
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(resp_ep)
    payload = encode_event("VisionRequest", "0123abcd", {"t_request": time.time()})
    try:
        # Slow joiner: ping until the first echo comes back, then drain the duplicates.
        first = asyncio.ensure_future(sub.recv())
        while not first.done():
            await pub.send(payload)
            await asyncio.wait({first}, timeout=0.01)
        while await sub.poll(50):
            await sub.recv()
        loop = asyncio.get_running_loop()
        samples = []
        for i in range(warmup + n):
            t0 = loop.time()
            await pub.send(payload)
            await sub.recv()
            if i >= warmup:
                samples.append(loop.time() - t0)
        # Stop the server: the echo of STOP tells us it got it (so closing with linger 0 loses nothing).
        while True:
            await pub.send(b"STOP")
            if await sub.poll(100) and await sub.recv() == b"STOP":
                break
        return samples
    finally:
        pub.close(0)
        sub.close(0)
        ctx.term()


async def _communicator_client(req_ep: str, resp_ep: str, n: int, warmup: int, queries: bool = False) -> list[float]:
    async with Communicator(req_ep, resp_ep, timeout_s=10, queries=queries) as comm:
        await comm.request("VisionRequest")  # joins (re-publishing as needed)
        loop = asyncio.get_running_loop()
        samples = []
        for i in range(warmup + n):
            t0 = loop.time()
            await comm.request("VisionRequest")
            if i >= warmup:
                samples.append(loop.time() - t0)
        # Ask the node to stop. It may close before its answer leaves (linger 0), so a timeout here is fine.
        try:
            await comm.request("STOP", timeout_s=0.5)
        except RequestTimeout:
            pass
        return samples


def _run(kind: str, n: int, warmup: int, *, pin: bool = False) -> list[float]:
    """One run of ``kind``. ``pin``: the requester on CPU 0 and the node on CPU 1, each in a process of its own
    started pinned, so every thread either side starts stays on its CPU (the requester then runs in a child process:
    this one's Zenoh runtime and ZeroMQ I/O thread may already exist, unpinned)."""
    if not pin:
        return _run_here(kind, n, warmup, None)
    parent, child = mp.Pipe()
    # not a daemon: it starts the node's process itself (the finally below ends it whatever happens)
    proc = mp.get_context("spawn").Process(target=_pinned, args=({0}, _requester, child, kind, n, warmup))
    proc.start()
    try:
        if not parent.poll(120):
            raise RuntimeError(f"the pinned {kind} requester did not report")
        result = parent.recv()
    finally:
        proc.join(10)
        if proc.is_alive():
            proc.kill()
    if isinstance(result, str):
        raise RuntimeError(f"the pinned {kind} requester failed: {result}")
    return result


def _requester(conn, kind: str, n: int, warmup: int) -> None:
    try:
        conn.send(_run_here(kind, n, warmup, {1}))
    except Exception as exc:  # reported to the parent, which raises it
        conn.send(repr(exc))


def _run_here(kind: str, n: int, warmup: int, node_cpus: set[int] | None) -> list[float]:
    if kind in ("zenoh", "raw_zenoh", "zenoh_query"):
        return _run_zenoh(n, warmup, raw=kind == "raw_zenoh", queries=kind == "zenoh_query", node_cpus=node_cpus)
    server = _raw_server if kind == "raw" else _responder_server
    client = _raw_client if kind == "raw" else _communicator_client
    proc, req, resp = _start(server, cpus=node_cpus)
    try:
        return asyncio.run(client(req, resp, n, warmup))
    finally:
        proc.join(5)
        if proc.is_alive():
            proc.kill()


def _run_zenoh(n: int, warmup: int, *, raw: bool = False, queries: bool = False,
               node_cpus: set[int] | None = None) -> list[float]:
    from aioadept.bus import zenoh as zb

    router = f"tcp/127.0.0.1:{_free_port()}"
    key = f"aioadept/bench/{os.urandom(4).hex()}"
    proc, req, resp = _start(_raw_zenoh_server if raw else _zenoh_responder_server, router, key, cpus=node_cpus)
    zb.configure(zb.ZenohOptions.client(router))
    try:
        if raw:
            return asyncio.run(_raw_zenoh_client(zb.session(), key, n, warmup))
        return asyncio.run(_communicator_client(req, resp, n, warmup, queries))
    finally:
        zb.close_session()
        proc.join(5)
        if proc.is_alive():
            proc.kill()


def _zenoh_version() -> str | None:
    try:
        from importlib.metadata import version

        import zenoh  # noqa: F401

        return version("eclipse-zenoh")
    except ImportError:
        return None


def _stats(samples: list[float]) -> dict[str, float]:
    s = sorted(samples)
    q = statistics.quantiles(s, n=100, method="inclusive")
    return {"n": len(s), "p50_us": round(q[49] * 1e6, 1), "p99_us": round(q[98] * 1e6, 1),
            "mean_us": round(statistics.fmean(s) * 1e6, 1), "min_us": round(s[0] * 1e6, 1)}


_PAIRS = (("ours", "raw"), ("zenoh", "ours"), ("zenoh_query", "ours"), ("raw_zenoh", "ours"))
"""(figure, baseline) of each per-round ratio: ours over raw pyzmq; the Zenoh kinds over ours on ZeroMQ."""


def _can_pin() -> bool:
    return hasattr(os, "sched_setaffinity") and {0, 1} <= os.sched_getaffinity(0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2000, help="measured round trips per round")
    ap.add_argument("--warmup", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=5,
                    help="alternating rounds; samples are pooled, and the Zenoh verdicts take the median round")
    args = ap.parse_args()

    zenoh_version = _zenoh_version()
    kinds = ["raw", "ours"] + (["raw_zenoh", "zenoh", "zenoh_query"] if zenoh_version is not None else [])
    pinnings = [False, True] if _can_pin() and zenoh_version is not None else [False]
    samples: dict[tuple[str, bool], list[float]] = {(k, p): [] for k in kinds for p in pinnings}
    per_round: dict[tuple[str, bool], list[float]] = {}
    for _ in range(args.rounds):  # alternate so drifting machine load hits all alike
        for pin in pinnings:
            medians = {}
            for kind in kinds if not pin else kinds[1:]:  # pinned: only what the Zenoh comparison needs
                got = _run(kind, args.n, args.warmup, pin=pin)
                samples[(kind, pin)] += got
                medians[kind] = statistics.median(got)
            for kind, baseline in _PAIRS:  # each figure over its baseline of the same round (where both ran)
                if kind in medians and baseline in medians:
                    per_round.setdefault((kind, pin), []).append(round(medians[kind] / medians[baseline], 3))
    stats = {key: _stats(v) for key, v in samples.items() if v}
    r, o = stats[("raw", False)], stats[("ours", False)]
    verdicts = [verdict("request->response p50, Communicator+Responder vs raw pyzmq", o["p50_us"], r["p50_us"],
                        unit="us", goal="ratio <= 1.3", passed=o["p50_us"] / r["p50_us"] <= 1.3)]
    out: dict = {}
    if zenoh_version is not None:
        for pin in pinnings:
            z, oz, zr = stats[("zenoh", pin)], stats[("ours", pin)], stats[("raw_zenoh", pin)]
            zq = stats[("zenoh_query", pin)]
            where = "each side pinned to a CPU of its own" if pin else "unpinned"
            # The goal is judged pinned where pinning is possible (the module docstring says why); unpinned is shown.
            judged = pin or len(pinnings) == 1
            ratio = statistics.median(per_round[("zenoh", pin)])
            verdicts.append(verdict(f"request->response p50, Communicator+Responder over Zenoh vs over ZeroMQ, "
                                    f"{where}, median round", z["p50_us"], oz["p50_us"], unit="us", ratio=ratio,
                                    goal="ratio <= 1.3" if judged else None, passed=ratio <= 1.3))
            verdicts.append(verdict(f"request->response p50, Communicator(queries=True)+Responder over Zenoh (Zenoh "
                                    f"queries) vs over ZeroMQ, {where}, median round", zq["p50_us"], oz["p50_us"],
                                    unit="us", ratio=statistics.median(per_round[("zenoh_query", pin)])))
            verdicts.append(verdict(f"request->response p50, raw Zenoh asyncio ping-pong (the floor) vs ours over "
                                    f"ZeroMQ, {where}, median round", zr["p50_us"], oz["p50_us"], unit="us",
                                    ratio=statistics.median(per_round[("raw_zenoh", pin)])))
            tag = "_pinned" if pin else ""
            out.update({
                f"communicator_responder_noop{tag}" if pin else "communicator_responder_noop_same_rounds": oz,
                f"communicator_responder_noop_zenoh{tag}": z,
                f"raw_zenoh_asyncio_pingpong{tag}": zr,
                f"zenoh_vs_zeromq_ratio_p50{tag}": round(z["p50_us"] / oz["p50_us"], 3),
                f"zenoh_vs_zeromq_ratio_p99{tag}": round(z["p99_us"] / oz["p99_us"], 3),
                f"zenoh_vs_zeromq_ratio_p50_per_round{tag}": per_round[("zenoh", pin)],
                f"zenoh_vs_zeromq_ratio_p50_median_round{tag}": ratio,
                f"communicator_responder_noop_zenoh_queries{tag}": zq,
                f"zenoh_queries_vs_zeromq_ratio_p50{tag}": round(zq["p50_us"] / oz["p50_us"], 3),
                f"zenoh_queries_vs_zeromq_ratio_p50_per_round{tag}": per_round[("zenoh_query", pin)],
                f"zenoh_queries_vs_publications_p50{tag}": round(zq["p50_us"] / z["p50_us"], 3),
                f"zenoh_floor_vs_zeromq_ours_p50{tag}": round(zr["p50_us"] / oz["p50_us"], 3),
                f"zenoh_ours_vs_floor_p50{tag}": round(z["p50_us"] / zr["p50_us"], 3),
            })
    print(json.dumps({
        "benchmark": "bus request->response latency, 127.0.0.1, server in a child process",
        "python": sys.version.split()[0], "pyzmq": zmq.__version__, "libzmq": zmq.zmq_version(),
        "machine": platform.machine(),
        "raw_pyzmq_pubsub_pingpong": r,
        "communicator_responder_noop": o,
        "ratio_p50": round(o["p50_us"] / r["p50_us"], 3),
        "ratio_p99": round(o["p99_us"] / r["p99_us"], 3),
        "ratio_mean": round(o["mean_us"] / r["mean_us"], 3),
        "ratio_p50_per_round": per_round[("ours", False)],
        "cpu_count": os.cpu_count(),
        "load_avg_1min": round(os.getloadavg()[0], 2),
        "target_ratio_p50": 1.3,
        "eclipse_zenoh": zenoh_version,
        "pinned_rounds": len(pinnings) == 2,
        **out,
        "verdicts": verdicts,
    }, indent=2))


if __name__ == "__main__":
    main()
