#!/usr/bin/env python3
"""The long fuzz run of the robot line protocol (issue E, part 1): millions of malformed and valid lines.

Outside the default test suite (it runs for minutes); the quick property tests live in ``tests/unit/fuzz/``.
Two phases, each fed ``--n`` inputs from one seeded generator (docs/fuzzing.md):

(a) **core**: the pure protocol core and the pure controller, in this process. Each input is a chunk of bytes
    (one line, several, a fragment, random bytes, an oversize line); it goes through a :class:`LineFramer` in
    random splits and whole (the results must agree), every framed item through :func:`parse_command` and
    :meth:`Controller.handle`. Exceptions are counted by type: only our protocol errors may come out of
    ``parse_command``, nothing out of the framer or the controller. Every framed item must get exactly one ack,
    an ``error`` ack whenever the parser rejects the line. Memory: tracemalloc current/peak, sampled.

(b) **sim**: a live ``aioadept sim --instant`` subprocess over ONE real TCP connection on 127.0.0.1. The same kind
    of input, in pipelined batches; a client-side framer predicts the framed items, so each must be answered by
    exactly one ack, in order, with the expected ID (``00000000`` when none is recoverable), and by an ``error``
    ack whenever the line is malformed. At the end a valid ``here`` must be acked ``done`` on the same
    connection, and the sim's stderr must hold no traceback. Memory: the sim's RSS (``/proc``), sampled.

Usage::

    .venv/bin/python scripts/fuzz_protocol.py --n 1000000            # both phases, ~2-4 min on 2 cores
    .venv/bin/python scripts/fuzz_protocol.py --n 20000 --phase core --seed 7 --json out.json

Prints a JSON report and exits 1 if any check failed.
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import json
import os
import random
import re
import socket
import subprocess
import sys
import time
import tracemalloc
from typing import Any

from aioadept.errors import ProtocolError, RemoteProtocolError
from aioadept.protocol import (
    MAX_ACK_LINE,
    MAX_LINE,
    NO_ID,
    LineFramer,
    Oversize,
    Status,
    parse_ack,
    parse_command,
    recover_id,
)
from aioadept.sim.controller import Controller

# -- the input generator ------------------------------------------------------------------------------------

_SKILLS = ("move_to", "move_joints", "move_rel_world", "move_rel_tool", "move_rel_joints", "break", "set_speed",
           "enable_air", "disable_air", "here", "hello")
_WEIRD_TOKENS = ("nan", "inf", "-inf", "1e5", "1E-3", "--1", "+-2", "1.2.3", "", " ", " 7 ", ".", "-.", "0x10",
                 "9" * 60, "-" + "9" * 40 + ".5", "1_000", "½", "\x00", "١٢", "+", ".5", "5.", "-0")
_INSERT = b":,.-+ \r\n\t\x00\xff0123456789eE"


class Inputs:
    """Seeded stream of fuzz inputs: valid command lines, mutated ones, random bytes, oversize lines."""

    def __init__(self, seed: int) -> None:
        self.r = random.Random(seed)
        self._n = 0

    def new_id(self) -> str:
        self._n += 1
        return "%08x" % ((self._n * 2654435761) & 0xFFFFFFFF or 1)

    def valid_line(self) -> bytes:
        r = self.r
        skill = r.choice(_SKILLS)
        mid = self.new_id()
        if skill == "move_to":
            args = [r.uniform(250, 600), r.uniform(-300, 300), r.uniform(150, 700), r.uniform(-180, 180),
                    r.uniform(150, 180), r.uniform(-180, 180)]
        elif skill == "move_joints":
            # Mostly inside the limits; sometimes beyond them (must be refused, pose unchanged).
            args = [r.uniform(-40, 40), r.uniform(-120, -60), r.uniform(140, 200), r.uniform(-30, 30),
                    r.uniform(40, 110), r.uniform(-90, 90)]
            if r.random() < 0.2:
                args[r.randrange(6)] = r.choice((-400.0, 400.0, 1e6))
        elif skill in ("move_rel_world", "move_rel_tool", "move_rel_joints"):
            args = [r.uniform(-5, 5) for _ in range(6)]
            if r.random() < 0.1:
                args[r.randrange(3)] = r.choice((-2000.0, 2000.0))
        elif skill == "set_speed":
            args = [r.choice((1, 5, 20, 50, 100, 0, 101, -3))]
        else:
            args = []
        if args:
            text = ",".join("%d" % a if isinstance(a, int) else "%.3f" % a for a in args)
            return f"{mid}:{skill}:{text}".encode()
        return f"{mid}:{skill}".encode()

    def mutate(self, line: bytes) -> bytes:
        r = self.r
        b = bytearray(line)
        for _ in range(r.randint(1, 4)):
            op = r.randrange(8)
            if op == 0 and b:  # flip a byte
                b[r.randrange(len(b))] = r.randrange(256)
            elif op == 1:  # insert a delimiter-ish byte
                b.insert(r.randint(0, len(b)), r.choice(_INSERT))
            elif op == 2 and b:  # delete a span
                i = r.randrange(len(b))
                del b[i:i + r.randint(1, 8)]
            elif op == 3 and b:  # truncate
                del b[r.randrange(len(b)):]
            elif op == 4:  # replace an argument with a weird token
                text = bytes(b).decode("latin-1")
                toks = re.split(r"([:,])", text)
                i = r.randrange(len(toks))
                toks[i] = r.choice(_WEIRD_TOKENS)
                b = bytearray("".join(toks).encode("utf-8", "replace"))
            elif op == 5 and b:  # duplicate a span
                i = r.randrange(len(b))
                j = min(len(b), i + r.randint(1, 40))
                b[i:i] = b[i:j]
            elif op == 6:  # uppercase/lowercase noise in the head (IDs accept A-Z, skills do not)
                b = bytearray(bytes(b).swapcase())
            else:  # glue another valid line without a delimiter
                b += self.valid_line()
        return bytes(b)

    def random_bytes(self) -> bytes:
        r = self.r
        n = r.choice((0, 1, 2, 8, 9, 20, 60, 127, 128, 129, 200, 300))
        if r.random() < 0.5:
            return r.randbytes(n)
        return bytes(r.choices(b"abcdef0123456789:,.-\r", k=n))

    def oversize(self) -> bytes:
        r = self.r
        head = self.valid_line() if r.random() < 0.5 else b""
        return head + bytes(r.choices(b"0123456789,.", k=r.randint(MAX_LINE, 3 * MAX_LINE)))

    def line(self) -> tuple[bytes, str]:
        """One input line (without delimiter) and its kind."""
        x = self.r.random()
        if x < 0.35:
            return self.valid_line(), "valid"
        if x < 0.80:
            return self.mutate(self.valid_line()), "mutated"
        if x < 0.95:
            return self.random_bytes(), "random"
        return self.oversize(), "oversize"

    def delimiter(self) -> bytes:
        x = self.r.random()
        return b"\r\n" if x < 0.8 else (b"\n" if x < 0.95 else b"\r\r\n")


def expected(item: bytes | Oversize) -> tuple[str, bool]:
    """(the ID the ack must carry, whether it must be an error ack) for one framed item, by the parser's rules."""
    if isinstance(item, Oversize):
        return recover_id(item.head) or NO_ID, True
    try:
        msg = parse_command(item)
    except RemoteProtocolError as exc:
        return exc.id or NO_ID, True
    return msg.id, False


def _mem_sample() -> int:
    return tracemalloc.get_traced_memory()[0]


def _progress(text: str) -> None:
    print(f"{time.strftime('%H:%M:%S')} {text}", file=sys.stderr, flush=True)


def rss_kib(pid: int) -> tuple[int, int]:
    """(VmRSS, VmHWM) of a process in KiB, from /proc."""
    rss = hwm = 0
    with open(f"/proc/{pid}/status") as f:
        for ln in f:
            if ln.startswith("VmRSS:"):
                rss = int(ln.split()[1])
            elif ln.startswith("VmHWM:"):
                hwm = int(ln.split()[1])
    return rss, hwm


# -- phase (a): the pure core ----------------------------------------------------------------------------------

def run_core(n: int, seed: int, *, trace_memory: bool = True) -> dict[str, Any]:
    gen = Inputs(seed)
    r = random.Random(seed + 1)
    kinds: collections.Counter[str] = collections.Counter()
    exc_parse: collections.Counter[str] = collections.Counter()
    exc_other: collections.Counter[str] = collections.Counter()
    codes: collections.Counter[int] = collections.Counter()
    framer_split, framer_whole = LineFramer(MAX_LINE), LineFramer(MAX_LINE)
    ctl = Controller(instant=True)
    ctl.connect("c")
    framed = acks = errors_expected = error_acks = missing_error = wrong_id = split_mismatch = moved_on_error = 0
    bad_examples: list[str] = []
    now = 0.0
    if trace_memory:
        tracemalloc.start()
    mem = [_mem_sample()] if trace_memory else []
    t0 = time.perf_counter()
    for i in range(n):
        line, kind = gen.line()
        kinds[kind] += 1
        data = line + gen.delimiter()
        # The same bytes whole and in random splits must frame identically.
        whole = framer_whole.feed(data)
        split: list[bytes | Oversize] = []
        pos = 0
        while pos < len(data):
            step = r.randint(1, max(1, len(data) - pos))
            split += framer_split.feed(data[pos:pos + step])
            pos += step
        if split != whole:
            split_mismatch += 1
        for item in whole:
            framed += 1
            want_id, must_err = expected(item)
            if not isinstance(item, Oversize):
                try:
                    parse_command(item)
                except ProtocolError as exc:
                    exc_parse[type(exc).__name__] += 1
                except Exception as exc:  # noqa: BLE001 - the point is to count anything unexpected
                    exc_other[f"parse_command:{type(exc).__name__}"] += 1
                    if len(bad_examples) < 10:
                        bad_examples.append(f"{type(exc).__name__}: {item!r}")
            now += 0.001
            joints_before = ctl.joints_at(now)  # at rest: every earlier motion was stepped to its end
            try:
                out = ctl.handle(item, "c", now)
                out += ctl.step(now + 10.0)  # let anything waiting (a break) finish
                now += 10.0
            except Exception as exc:  # noqa: BLE001
                exc_other[f"controller:{type(exc).__name__}"] += 1
                if len(bad_examples) < 10:
                    bad_examples.append(f"{type(exc).__name__}: {item!r}")
                continue
            acks += len(out)
            if len(out) != 1:
                if len(bad_examples) < 10:
                    bad_examples.append(f"{len(out)} acks for {item!r}")
                continue
            ack = out[0].ack
            if ack.id != want_id:
                wrong_id += 1
            if must_err:
                errors_expected += 1
                if ack.status is not Status.ERROR:
                    missing_error += 1
            if ack.status is Status.ERROR:
                error_acks += 1
                codes[ack.error_code or 0] += 1
                if ctl.joints_at(now) != joints_before:  # refused, yet the arm moved
                    moved_on_error += 1
        if i % 10000 == 0:
            if trace_memory:
                mem.append(_mem_sample())
            if i % 100_000 == 0:
                _progress(f"core {i}/{n}")
    elapsed = time.perf_counter() - t0
    result: dict[str, Any] = {
        "inputs": n, "input_kinds": dict(kinds), "framed_items": framed, "acks": acks,
        "seconds": round(elapsed, 2), "inputs_per_s": round(n / elapsed),
        "parse_exceptions_by_type": dict(exc_parse), "unexpected_exceptions": dict(exc_other),
        "malformed_items": errors_expected, "malformed_without_error_ack": missing_error,
        "error_acks": error_acks, "error_acks_that_moved_the_arm": moved_on_error, "error_codes": {str(k): v for k, v in sorted(codes.items())},
        "acks_with_wrong_id": wrong_id, "split_vs_whole_framing_mismatches": split_mismatch,
        "framer_buffered_at_end": framer_whole.buffered, "controller_queue_at_end": ctl.queued(),
        "joints_within_limits_at_end": _within_limits(ctl), "examples": bad_examples,
    }
    if trace_memory:
        _, peak = tracemalloc.get_traced_memory()
        mem.append(_mem_sample())
        tracemalloc.stop()
        result["tracemalloc_kib"] = {"start": mem[0] // 1024, "peak": peak // 1024, "end": mem[-1] // 1024,
                                     "samples": len(mem)}
    result["ok"] = (framed == acks and not exc_other and missing_error == 0 and wrong_id == 0 and moved_on_error == 0
                    and split_mismatch == 0 and result["joints_within_limits_at_end"])
    return result


def _within_limits(ctl: Controller) -> bool:
    try:
        ctl.joint_limits.check(ctl.joints_deg)
    except Exception:  # noqa: BLE001
        return False
    return True


# -- phase (b): a live sim over one TCP connection --------------------------------------------------------------

def start_sim() -> tuple[subprocess.Popen[str], str, int]:
    cmd = [sys.executable, "-m", "aioadept.sim", "--port", "0", "--instant", "--state-endpoint", "none",
           "--log-level", "ERROR"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    ready = proc.stdout.readline()  # the sim prints READY once it listens: no sleep
    m = re.match(r"READY host=(\S+) port=(\d+)", ready)
    if not m:
        proc.kill()
        raise SystemExit(f"sim did not start: {ready!r} {proc.stderr.read() if proc.stderr else ''}")
    return proc, m.group(1), int(m.group(2))


async def run_sim(n: int, seed: int, batch: int) -> dict[str, Any]:
    proc, host, port = start_sim()
    try:
        return await _drive_sim(proc, host, port, n, seed, batch)
    finally:
        proc.terminate()
        try:
            _, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
        _sim_stderr.append(err)


_sim_stderr: list[str] = []


async def _drive_sim(proc: subprocess.Popen[str], host: str, port: int, n: int, seed: int,
                     batch: int) -> dict[str, Any]:
    gen = Inputs(seed)
    reader, writer = await asyncio.open_connection(host, port, limit=MAX_ACK_LINE * 4)
    sock = writer.get_extra_info("socket")
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    predictor = LineFramer(MAX_LINE)
    acks_framer = LineFramer(MAX_ACK_LINE)
    kinds: collections.Counter[str] = collections.Counter()
    codes: collections.Counter[int] = collections.Counter()
    client_errors: collections.Counter[str] = collections.Counter()
    sent = framed = acked = malformed = missing_error = wrong_id = 0
    examples: list[str] = []
    rss = [rss_kib(proc.pid)]
    t0 = time.perf_counter()
    while sent < n:
        chunk = bytearray()
        want: collections.deque[tuple[str, bool, bytes]] = collections.deque()
        for _ in range(min(batch, n - sent)):
            line, kind = gen.line()
            kinds[kind] += 1
            data = line + gen.delimiter()
            chunk += data
            for item in predictor.feed(data):
                want.append((*expected(item), item.head if isinstance(item, Oversize) else item))
            sent += 1
        framed += len(want)
        writer.write(bytes(chunk))
        # Read exactly the predicted number of acks back (the sim acks every framed item once, in order).
        while want:
            data = await asyncio.wait_for(reader.read(65536), timeout=30)
            if not data:
                raise ConnectionError(f"sim closed the connection after {acked} acks")
            for raw in acks_framer.feed(data):
                if isinstance(raw, Oversize):
                    client_errors["Oversize ack"] += 1
                    continue
                try:
                    ack = parse_ack(raw)
                except RemoteProtocolError as exc:
                    client_errors[type(exc).__name__] += 1
                    continue
                acked += 1
                if not want:
                    client_errors["unexpected extra ack"] += 1
                    continue
                want_id, must_err, line = want.popleft()
                if ack.id != want_id:
                    wrong_id += 1
                    if len(examples) < 10:
                        examples.append(f"ack {ack.id} for {line!r} (wanted {want_id})")
                if must_err:
                    malformed += 1
                    if ack.status is not Status.ERROR:
                        missing_error += 1
                        if len(examples) < 10:
                            examples.append(f"{ack.status.value} for malformed {line!r}")
                if ack.status is Status.ERROR:
                    codes[ack.error_code or 0] += 1
        if sent // batch % 20 == 0:
            rss.append(rss_kib(proc.pid))
        if sent % 100_000 < batch:
            _progress(f"sim {sent}/{n}")
    elapsed = time.perf_counter() - t0
    rss.append(rss_kib(proc.pid))
    # The connection must still be usable: a valid here, acked done.
    writer.write(b"fffffff0:here\r\n")
    final = None
    while final is None:
        data = await asyncio.wait_for(reader.read(65536), timeout=10)
        if not data:
            break
        for raw in acks_framer.feed(data):
            if not isinstance(raw, Oversize):
                ack = parse_ack(raw)
                if ack.id == "fffffff0":
                    final = ack
    writer.close()
    await writer.wait_closed()
    return {
        "lines_sent": sent, "input_kinds": dict(kinds), "framed_items": framed, "acks": acked,
        "seconds": round(elapsed, 2), "lines_per_s": round(sent / elapsed), "batch": batch,
        "malformed_items": malformed, "malformed_without_error_ack": missing_error,
        "acks_with_wrong_id": wrong_id, "error_codes": {str(k): v for k, v in sorted(codes.items())},
        "client_side_errors": dict(client_errors),
        "final_here": None if final is None else {"status": final.status.value, "pose": list(final.pose)},
        "sim_rss_kib": {"start": rss[0][0], "peak_hwm": rss[-1][1], "end": rss[-1][0],
                        "max_sampled": max(s[0] for s in rss), "samples": len(rss)},
        "examples": examples,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=1_000_000, help="inputs per phase")
    p.add_argument("--seed", type=int, default=20190601)
    p.add_argument("--phase", choices=("core", "sim", "both"), default="both")
    p.add_argument("--batch", type=int, default=500, help="lines per write in the sim phase")
    p.add_argument("--no-tracemalloc", action="store_true", help="core phase without tracemalloc (faster)")
    p.add_argument("--json", help="also write the report here")
    args = p.parse_args(argv)
    report: dict[str, Any] = {"n": args.n, "seed": args.seed, "python": sys.version.split()[0],
                              "cpus": os.cpu_count()}
    ok = True
    if args.phase in ("core", "both"):
        report["core"] = run_core(args.n, args.seed, trace_memory=not args.no_tracemalloc)
        ok &= report["core"]["ok"]
    if args.phase in ("sim", "both"):
        sim = asyncio.run(run_sim(args.n, args.seed + 100, args.batch))
        err = "".join(_sim_stderr)
        sim["sim_stderr_tracebacks"] = err.count("Traceback")
        sim["sim_stderr_tail"] = err[-2000:]
        sim["ok"] = (sim["framed_items"] == sim["acks"] and sim["malformed_without_error_ack"] == 0
                     and sim["acks_with_wrong_id"] == 0 and not sim["client_side_errors"]
                     and sim["final_here"] is not None and sim["final_here"]["status"] == "done"
                     and sim["sim_stderr_tracebacks"] == 0)
        report["sim"] = sim
        ok &= sim["ok"]
    report["ok"] = bool(ok)
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
