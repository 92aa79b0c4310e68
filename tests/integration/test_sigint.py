"""Ctrl-C anywhere: a real SIGINT to a real ``aioadept focus`` / ``demo`` / ``send`` process.

The robot is a separate ``aioadept sim`` process (for ``demo``, the one the demo starts, at an address the test
chose); what the arm does is read from the sim's ZeroMQ state stream ``robot.state``, never from the app under
test. Motions run in real time (time scale 1) and slowly, so the signal lands in the middle of one. What must hold:

- the first SIGINT stops the arm (at rest within 2 s here; the benchmark measures the real latency) and no motion
  starts afterwards (no retract, no next step); the app exits 130 with one line saying the robot stopped, no
  traceback; the run folder keeps what was recorded;
- a stop that fails is an error (exit 1 for the apps, 3 for send), not a clean interrupt;
- a second SIGINT exits at once, killing the demo's node processes.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import sys
from pathlib import Path

import pytest

from aioadept.ports import free_port
from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
from aioadept.bus.pubsub import Subscriber
from aioadept.geometry import Pose, rel_tool
from aioadept.protocol import Ack, LineFramer, Status, encode_ack, parse_command
from aioadept.testing.nodes import running_node

AIOADEPT = [sys.executable, "-m", "aioadept"]
SLOW_SPEED = 1  # % : a focus step of 40 mm takes 3 s in real time, so finishing it would miss the 2 s bound
POSE = Pose(480.0, 0.0, 710.0, 0.0, 180.0, 0.0)


class StateWatch:
    """The sim's state stream as (receive time, RobotState) samples, read by the test process."""

    def __init__(self, endpoint: str) -> None:
        self.sub = Subscriber(endpoint, topics=[ROBOT_STATE_TOPIC])
        self.samples: list[tuple[float, RobotState]] = []

    async def next(self) -> tuple[float, RobotState]:
        _topic, payload = await self.sub.recv()
        sample = (asyncio.get_running_loop().time(), RobotState.from_bytes(payload))
        self.samples.append(sample)
        return sample

    async def until(self, predicate, what: str, *, timeout_s: float) -> tuple[float, RobotState]:
        try:
            async with asyncio.timeout(timeout_s):
                while True:
                    t, st = await self.next()
                    if predicate(st):
                        return t, st
        except TimeoutError:
            last = self.samples[-1][1] if self.samples else None
            raise AssertionError(f"no state sample {what} within {timeout_s} s (last: {last})") from None

    async def collect_for(self, seconds: float) -> list[RobotState]:
        """Every sample of the next ``seconds`` (an observation window: that nothing moves in it is the point)."""
        out: list[RobotState] = []
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(seconds):
                while True:
                    out.append((await self.next())[1])
        return out

    def close(self) -> None:
        self.sub.close()


def moving_at(speed: int):
    return lambda st: st.in_motion and st.speed_pct == speed


def at_rest(st: RobotState) -> bool:
    return not st.in_motion


async def _spawn(*args: str) -> asyncio.subprocess.Process:
    return await asyncio.create_subprocess_exec(*AIOADEPT, *args, stdin=asyncio.subprocess.DEVNULL,
                                                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)


async def _finish(proc: asyncio.subprocess.Process, timeout_s: float = 20.0) -> tuple[str, str]:
    try:
        async with asyncio.timeout(timeout_s):
            out, err = await proc.communicate()
    except TimeoutError:
        proc.kill()
        out, err = await proc.communicate()
        raise AssertionError(f"did not exit within {timeout_s} s:\n{err.decode(errors='replace')}") from None
    return out.decode(errors="replace"), err.decode(errors="replace")


async def _stderr_line(proc: asyncio.subprocess.Process, needle: str, seen: list[str], *, timeout_s: float) -> None:
    assert proc.stderr is not None
    async with asyncio.timeout(timeout_s):
        while True:
            raw = await proc.stderr.readline()
            if not raw:
                raise AssertionError(f"stderr ended before {needle!r}:\n{''.join(seen)}")
            seen.append(raw.decode(errors="replace"))
            if needle in seen[-1]:
                return


def _live_cmdlines() -> list[str]:
    out = []
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                raw = Path(f"/proc/{pid}/cmdline").read_bytes()
            except OSError:
                continue
            if raw:
                out.append(" ".join(a.decode(errors="replace") for a in raw.rstrip(b"\0").split(b"\0")))
    return out


async def _gone(marker: str, *, timeout_s: float = 5.0) -> None:
    """Wait until no process has ``marker`` in its command line (a SIGKILLed child is reaped a moment later)."""
    async with asyncio.timeout(timeout_s):
        while any(marker in c for c in _live_cmdlines()):
            await asyncio.sleep(0.02)


def _assert_no_motion_after(rest: RobotState, later: list[RobotState]) -> None:
    assert later, "the state stream went silent"
    moved = [st for st in later if st.in_motion or st.pose.translation_distance_mm(rest.pose) > 0.01]
    assert not moved, f"a motion started after the stop: {moved[0]}"


@contextlib.asynccontextmanager
async def sim_and_vision(tmp_path: Path, *, focus_offset_mm: float = 200.0):
    """``aioadept sim`` (real time) and ``aioadept vision`` as processes, and a watch on the sim's state stream."""
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "sim.log") as sim, \
            running_node("vision", "--state-endpoint", sim.ready["state"], "--request-endpoint", "tcp://127.0.0.1:0",
                         "--response-endpoint", "tcp://127.0.0.1:0", "--focus-offset-mm", str(focus_offset_mm), "--policy", "after",
                         log_path=tmp_path / "vision.log") as vision:
        watch = StateWatch(sim.ready["state"])
        try:
            await watch.until(lambda st: True, "at all (the subscription is live)", timeout_s=10)
            yield sim, vision, watch
        finally:
            watch.close()


def _focus_args(sim, vision, out: Path) -> list[str]:
    return ["focus", "--robot", f"127.0.0.1:{sim.ready['port']}", "--request-endpoint", vision.ready["request"],
            "--response-endpoint", vision.ready["response"], "--out", str(out), "--no-analyze",
            "--speed", str(SLOW_SPEED), "--delta-z", "40", "--max-steps", "5", "--vision-timeout", "20"]


# --------------------------------------------------------------------------------------------- aioadept focus
@pytest.mark.timeout(120)
async def test_focus_first_sigint_stops_the_arm_mid_step_and_starts_no_motion(tmp_path):
    async with sim_and_vision(tmp_path) as (sim, vision, watch):
        proc = await _spawn(*_focus_args(sim, vision, tmp_path / "runs"))
        try:
            # A focus step (the approach speed, not init_move's) is under way.
            await watch.until(moving_at(SLOW_SPEED), f"moving at {SLOW_SPEED} %", timeout_s=60)
            t_kill = asyncio.get_running_loop().time()
            os.kill(proc.pid, signal.SIGINT)
            t_rest, rest = await watch.until(at_rest, "at rest", timeout_s=5)
            out, err = await _finish(proc)
            later = await watch.collect_for(1.0)  # the app is gone: nothing may move now (no retract)
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    assert t_rest - t_kill < 2.0, f"at rest {t_rest - t_kill:.3f} s after SIGINT"
    _assert_no_motion_after(rest, later)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "Traceback" not in out
    assert "interrupted: robot stopped" in err
    # What was recorded up to the interrupt is kept, and says why the run ended.
    (run_dir,) = (tmp_path / "runs").iterdir()
    assert json.loads((run_dir / "focus.json").read_text()) == {"error": "interrupted"}
    assert json.loads((run_dir / "run.json").read_text())["parameters"]["error"] == "interrupted"


async def _no_stop_server(lines: list[bytes], broken: asyncio.Event, *, stop_reply: str, hold_break: bool = False):
    """A robot server that acks everything ``done`` at once but does not stop: ``stop_reply`` "error" answers the
    stop with an error ack (a server without the extension), "silent" never answers it (a V+ task that halted).
    ``hold_break``: never ack ``break`` (a motion that goes on)."""

    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        framer = LineFramer()
        with contextlib.suppress(ConnectionError):
            while data := await reader.read(4096):
                for line in framer.feed(data):
                    lines.append(bytes(line))
                    msg = parse_command(line)
                    if msg.skill == "stop":
                        broken.set()
                        if stop_reply == "error":
                            writer.write(encode_ack(Ack.error(msg.id, -406, "undefined skill stop", 1.0, 1.0, POSE)))
                        continue
                    if hold_break and msg.skill == "break":
                        continue
                    writer.write(encode_ack(Ack(msg.id, Status.DONE, 1.0, 1.0, POSE, ())))
        writer.close()

    return await asyncio.start_server(serve, "127.0.0.1", 0)


@pytest.mark.timeout(60)
async def test_focus_sigint_whose_stop_fails_is_an_error_not_a_clean_interrupt(tmp_path):
    # The robot server refuses `stop`; the focus app waits for a vision answer that never comes (nobody listens).
    lines: list[bytes] = []
    stop_seen = asyncio.Event()
    server = await _no_stop_server(lines, stop_seen, stop_reply="error")
    port = server.sockets[0].getsockname()[1]
    async with server:
        proc = await _spawn("focus", "--robot", f"127.0.0.1:{port}", "--request-endpoint",
                            f"tcp://127.0.0.1:{free_port()}", "--response-endpoint", f"tcp://127.0.0.1:{free_port()}",
                            "--out", str(tmp_path), "--no-analyze", "--vision-timeout", "30")
        try:
            async with asyncio.timeout(30):  # init_move is done: four motions with their breaks were acked
                while sum(1 for line in lines if line.endswith(b":break")) < 4:
                    await asyncio.sleep(0.01)
            os.kill(proc.pid, signal.SIGINT)
            out, err = await _finish(proc)
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    assert stop_seen.is_set()
    assert proc.returncode == 1, err
    assert "Traceback" not in err
    assert "the stop FAILED" in err and "undefined skill stop" in err and "may still be moving" in err
    assert "robot stopped" not in err
    # Nothing was sent after the stop: no retract.
    assert lines[-1].endswith(b":stop"), lines[-3:]


# --------------------------------------------------------------------------------------------- aioadept send
@pytest.mark.timeout(60)
async def test_send_sigint_stops_the_move_and_sends_nothing_after(tmp_path):
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "sim.log") as sim:
        watch = StateWatch(sim.ready["state"])
        try:
            await watch.until(lambda st: True, "at all", timeout_s=10)
            proc = await _spawn("send", "--port", sim.ready["port"], "set_speed:1", "move_rel_joints:60,0,0,0,0,0",
                                "break", "set_speed:100", "move_rel_joints:-60,0,0,0,0,0", "break")
            try:
                await watch.until(moving_at(1), "moving at 1 %", timeout_s=20)
                t_kill = asyncio.get_running_loop().time()
                os.kill(proc.pid, signal.SIGINT)
                t_rest, rest = await watch.until(at_rest, "at rest", timeout_s=5)
                out, err = await _finish(proc)
                later = await watch.collect_for(1.0)
            finally:
                if proc.returncode is None:
                    proc.kill()
                    await proc.wait()
        finally:
            watch.close()
    assert t_rest - t_kill < 2.0
    _assert_no_motion_after(rest, later)  # the second move of the list never ran
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted: robot stopped" in err


@pytest.mark.timeout(60)
async def test_send_second_sigint_exits_at_once_while_the_stop_is_unanswered():
    lines: list[bytes] = []
    stop_seen = asyncio.Event()
    server = await _no_stop_server(lines, stop_seen, stop_reply="silent", hold_break=True)
    port = server.sockets[0].getsockname()[1]
    async with server:
        # The break is never acked (the motion goes on), nor the stop: the first interrupt waits for the stop's ack
        # (up to the 30 s ack timeout) when the second comes.
        proc = await _spawn("send", "--port", str(port), "--timeout", "30", "move_rel_joints:60,0,0,0,0,0", "break")
        seen: list[str] = []
        try:
            async with asyncio.timeout(20):
                while not any(line.endswith(b":break") for line in lines):
                    await asyncio.sleep(0.005)
            os.kill(proc.pid, signal.SIGINT)
            await stop_seen.wait()
            await _stderr_line(proc, "press Ctrl-C again", seen, timeout_s=10)
            t0 = asyncio.get_running_loop().time()
            os.kill(proc.pid, signal.SIGINT)
            out, err = await _finish(proc, timeout_s=10)
            t_exit = asyncio.get_running_loop().time() - t0
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    err = "".join(seen) + err
    assert proc.returncode == 130, err
    assert t_exit < 2.0, f"second SIGINT: exit after {t_exit:.3f} s"
    assert "exiting now" in err and "Traceback" not in err
    assert sum(1 for line in lines if line.endswith(b":stop")) >= 1


# --------------------------------------------------------------------------------------------- aioadept demo
def _demo_config(tmp_path: Path, state_endpoint: str, sim_args: list[str] = (), hello_timeout_s: float = 2.0) -> Path:
    cfg = tmp_path / "cell.toml"
    cfg.write_text(
        f"[robot]\nport = 0\nhello_timeout_s = {hello_timeout_s}\n"
        f'state_endpoint = "{state_endpoint}"\n'
        f"sim_args = {json.dumps(list(sim_args))}\n"
        "[vision]\n"
        'request_endpoint = "tcp://127.0.0.1:0"\nresponse_endpoint = "tcp://127.0.0.1:0"\n'
        "focus_offset_mm = 200.0\n"
        f"[run]\nout_dir = \"{tmp_path / 'runs'}\"\nanalyze = false\n")
    return cfg


@pytest.mark.timeout(120)
async def test_demo_first_sigint_stops_the_arm_then_the_nodes_and_exits_130(tmp_path):
    state = f"tcp://127.0.0.1:{free_port()}"
    watch = StateWatch(state)  # connects before the demo's sim binds: ZeroMQ retries
    try:
        proc = await _spawn("demo", "--config", str(_demo_config(tmp_path, state)), "--speed", str(SLOW_SPEED),
                            "--delta-z", "40", "--max-steps", "5")
        try:
            await watch.until(moving_at(SLOW_SPEED), f"moving at {SLOW_SPEED} %", timeout_s=60)
            t_kill = asyncio.get_running_loop().time()
            os.kill(proc.pid, signal.SIGINT)
            t_rest, _rest = await watch.until(at_rest, "at rest", timeout_s=5)
            out, err = await _finish(proc, timeout_s=30)
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    finally:
        watch.close()
    assert t_rest - t_kill < 2.0, f"at rest {t_rest - t_kill:.3f} s after SIGINT"
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted: robot stopped" in err
    await _gone(state)  # the sim and the vision node (both have the state endpoint in their command line)


@pytest.mark.timeout(120)
async def test_demo_second_sigint_exits_at_once_and_kills_the_nodes(tmp_path):
    # The sim acks 3 s late, so the first interrupt is still waiting for the stop's ack when the second comes (and
    # the connect-time hello check, 2 s, is off: its answer would come late too).
    state = f"tcp://127.0.0.1:{free_port()}"
    watch = StateWatch(state)
    seen: list[str] = []
    try:
        proc = await _spawn("demo", "--config", str(_demo_config(tmp_path, state, ["--fault", "ack-delay=3"], hello_timeout_s=0)))
        try:
            await watch.until(lambda st: st.in_motion, "in motion", timeout_s=60)
            os.kill(proc.pid, signal.SIGINT)
            await _stderr_line(proc, "press Ctrl-C again", seen, timeout_s=10)
            await watch.until(at_rest, "at rest", timeout_s=5)  # the stop acted; its ack is still on its way
            assert any(c for c in _live_cmdlines() if state in c), "the nodes should still run here"
            t0 = asyncio.get_running_loop().time()
            os.kill(proc.pid, signal.SIGINT)
            out, err = await _finish(proc, timeout_s=10)
            t_exit = asyncio.get_running_loop().time() - t0
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    finally:
        watch.close()
    err = "".join(seen) + err
    assert proc.returncode == 130, err
    assert t_exit < 2.0, f"second SIGINT: exit after {t_exit:.3f} s"
    assert "exiting now" in err and "Traceback" not in err
    await _gone(state)


# --------------------------------------------------------------------------------------------- aioadept experiment
@pytest.mark.timeout(120)
async def test_experiment_first_sigint_stops_the_arm_and_ends_the_whole_grid(tmp_path):
    state = f"tcp://127.0.0.1:{free_port()}"
    watch = StateWatch(state)
    try:
        proc = await _spawn("experiment", "--config", str(_demo_config(tmp_path, state)), "--speeds",
                            f"{SLOW_SPEED},{SLOW_SPEED}", "--delta-z", "40", "--runs", "2", "--out", str(tmp_path / "x"))
        try:
            await watch.until(moving_at(SLOW_SPEED), f"moving at {SLOW_SPEED} %", timeout_s=60)
            t_kill = asyncio.get_running_loop().time()
            os.kill(proc.pid, signal.SIGINT)
            t_rest, rest = await watch.until(at_rest, "at rest", timeout_s=5)
            later = await watch.collect_for(0.5)  # no next run starts a motion (the nodes may be stopping)
            out, err = await _finish(proc, timeout_s=30)
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    finally:
        watch.close()
    assert t_rest - t_kill < 2.0, f"at rest {t_rest - t_kill:.3f} s after SIGINT"
    assert not [st for st in later if st.in_motion]
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted: robot stopped" in err
    assert not (tmp_path / "x" / "analysis").exists()  # no analysis of an interrupted grid
    await _gone(state)


# --------------------------------------------------------------------------------------------- SIGHUP
def _controlling_tty() -> None:
    """For the child, after setsid (start_new_session): make its stdin, a pty slave, the controlling terminal, so that
    closing the master is a real hangup (the kernel sends SIGHUP to the session's controlling process)."""
    import fcntl
    import termios

    fcntl.ioctl(0, termios.TIOCSCTTY, 0)


@pytest.mark.timeout(60)
async def test_send_stops_the_arm_when_its_terminal_goes_away(tmp_path):
    # The case: `aioadept send set_speed:.. move_rel_tool:0,0,60,0,0,0 break` in a terminal (or an SSH
    # session) that closes. The terminal is a pty whose master this test holds; closing it hangs the terminal up.
    loop = asyncio.get_running_loop()
    async with running_node("sim", "--port", "0", "--state-endpoint", "tcp://127.0.0.1:0",
                            log_path=tmp_path / "sim.log") as sim:
        watch = StateWatch(sim.ready["state"])
        master, slave = os.openpty()
        master_open = True
        try:
            _t, start = await watch.until(lambda st: True, "at all", timeout_s=10)
            target = rel_tool(start.pose, (0.0, 0.0, 60.0, 0.0, 0.0, 0.0))
            proc = await asyncio.create_subprocess_exec(
                *AIOADEPT, "send", "--port", sim.ready["port"], f"set_speed:{SLOW_SPEED}", "move_rel_tool:0,0,60,0,0,0",
                "break", stdin=slave, stdout=slave, stderr=slave, start_new_session=True,
                preexec_fn=_controlling_tty)
            os.close(slave)
            terminal: list[bytes] = []

            def drain() -> None:  # keep the terminal readable, as a terminal emulator does
                try:
                    data = os.read(master, 4096)
                except OSError:  # EIO: the app has gone (and with it the terminal's last reader)
                    data = b""
                if data:
                    terminal.append(data)
                else:
                    loop.remove_reader(master)

            loop.add_reader(master, drain)
            try:
                await watch.until(moving_at(SLOW_SPEED), f"moving at {SLOW_SPEED} %", timeout_s=20)
                t_hup = loop.time()
                loop.remove_reader(master)
                os.close(master)  # the terminal goes away: SIGHUP
                master_open = False
                t_rest, rest = await watch.until(at_rest, "at rest", timeout_s=5)
                async with asyncio.timeout(20):
                    await proc.wait()
                later = await watch.collect_for(1.0)
            finally:
                if proc.returncode is None:
                    proc.kill()
                    await proc.wait()
        finally:
            if master_open:
                loop.remove_reader(master)
                os.close(master)
            watch.close()
    # Today's code: the process dies of the signal (-1) and the 60 mm move runs to its end.
    moved_mm = rest.pose.translation_distance_mm(start.pose)
    assert rest.pose.translation_distance_mm(target) > 30.0, f"the move ran on after the hangup ({moved_mm:.1f} mm)"
    assert t_rest - t_hup < 2.0, f"at rest {t_rest - t_hup:.3f} s after the hangup"
    assert proc.returncode == 130, (proc.returncode, b"".join(terminal))  # the stop was acked
    _assert_no_motion_after(rest, later)


@pytest.mark.timeout(120)
async def test_demo_sighup_stops_the_arm_then_the_nodes_and_exits_130(tmp_path):
    # The demo's nodes run in sessions of their own: a hangup reaches the app only, which stops the arm first.
    state = f"tcp://127.0.0.1:{free_port()}"
    watch = StateWatch(state)
    try:
        proc = await _spawn("demo", "--config", str(_demo_config(tmp_path, state)), "--speed", str(SLOW_SPEED),
                            "--delta-z", "40", "--max-steps", "5")
        try:
            await watch.until(moving_at(SLOW_SPEED), f"moving at {SLOW_SPEED} %", timeout_s=60)
            t_hup = asyncio.get_running_loop().time()
            os.kill(proc.pid, signal.SIGHUP)
            t_rest, rest = await watch.until(at_rest, "at rest", timeout_s=5)
            later = await watch.collect_for(0.5)
            out, err = await _finish(proc, timeout_s=30)
        finally:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
    finally:
        watch.close()
    assert t_rest - t_hup < 2.0, f"at rest {t_rest - t_hup:.3f} s after SIGHUP"
    assert not [st for st in later if st.in_motion]
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "SIGHUP: stopping the robot" in err and "interrupted: robot stopped" in err
    await _gone(state)
