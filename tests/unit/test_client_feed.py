"""The client's registry (PendingCalls, sans-IO) driven with bytes: its inline ack fast path gives exactly what
the general parser gives, acks reach their messages, a lost connection fails them all (no sockets, no loop)."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from aioadept.client import PendingCalls
from aioadept.commands import Skill
from aioadept.errors import RemoteProtocolError
from aioadept.geometry import Pose
from aioadept.protocol import Ack, Status, encode_ack, parse_ack

POSES = [Pose(1, 2, 3, 4, 5, 6), Pose(480.014, -0.038, 709.975, 0.0, 179.995, 0.004)]


class Box:
    """A future double: what the registry needs of a per-message future or a waiter."""

    def __init__(self) -> None:
        self.value: object = None
        self.error: BaseException | None = None
        self._done = False

    def done(self) -> bool:
        return self._done

    def set_result(self, value: object) -> None:
        assert not self._done
        self.value, self._done = value, True

    def set_exception(self, exc: BaseException) -> None:
        assert not self._done
        self.error, self._done = exc, True

    def result(self) -> object:
        assert self._done and self.error is None
        return self.value


class Wired:
    """A registry and what a client would have written through it."""

    def __init__(self, id_start: int = 0x1000) -> None:
        self.reg = PendingCalls(id_start=id_start)
        self.stats = self.reg.stats
        self.written: list[bytes] = []

    def submit(self, *commands):
        calls = tuple(c for command in commands for c in command.calls())
        sub, wire = self.reg.register(calls, Box)
        self.written.append(wire)
        return sub

    def feed(self, data: bytes, t_recv: float) -> None:
        self.reg.receive(data, t_recv)

    @property
    def pending_ids(self) -> tuple[str, ...]:
        return self.reg.pending_ids


def wired_client() -> tuple[Wired, list[bytes]]:
    w = Wired()
    return w, w.written


line_kind = st.sampled_from(["done", "done_same", "error", "aborted", "bad_time", "inf_time", "unknown", "extra"])


@settings(max_examples=150, deadline=None)
@given(kinds=st.lists(st.tuples(line_kind, st.integers(0, 1), st.floats(-1e4, 1e4, allow_nan=False)),
                      min_size=1, max_size=12),
       split=st.integers(1, 7))
def test_inline_fast_path_matches_parse_ack(kinds, split):
    robot, written = wired_client()
    try:
        sub = robot.submit(*[Skill("noop", k) for k in range(len(kinds))])
        lines = []
        for mid, (kind, pose_i, t) in zip(sub.ids, kinds, strict=True):
            pose = POSES[pose_i]
            if kind in ("done", "done_same"):
                line = encode_ack(Ack(mid, Status.DONE, t, t + 1, pose))
            elif kind == "error":
                line = encode_ack(Ack.error(mid, -610, "out of range", t, t, pose))
            elif kind == "aborted":
                line = encode_ack(Ack(mid, Status.ABORTED, t, t, pose))
            elif kind == "extra":
                line = encode_ack(Ack(mid, Status.DONE, t, t, pose, ("1", "x")))
            elif kind == "bad_time":
                line = encode_ack(Ack(mid, Status.DONE, t, t, pose)).replace(b":done:", b":done:x", 1)
            elif kind == "inf_time":
                line = f"{mid}:done:inf,1.000:".encode() + encode_ack(Ack(mid, Status.DONE, 0, 0, pose)).split(
                    b":")[3]
            else:
                line = encode_ack(Ack("ffffffff" if mid != "ffffffff" else "fffffffe", Status.DONE, t, t, pose))
            lines.append(line)
        stream = b"".join(lines)
        for k in range(0, len(stream), split * 37):
            robot.feed(stream[k:k + split * 37], 5.0)
        for i, line in enumerate(lines):
            try:
                want = parse_ack(line.rstrip(b"\r\n"))
            except RemoteProtocolError:
                want = None
            got = sub.results[i]
            if want is None or want.id != sub.ids[i]:
                assert got is None  # garbage or someone else's ID: not routed to this message
            else:
                assert got is not None and got.ack == want
                assert (got.id, got.skill, got.args, got.t_recv_s) == (sub.ids[i], "noop", (i,), 5.0)
                assert sub.futures[i].result() is got
        routed = sum(r is not None for r in sub.results)
        assert robot.stats.acks == routed
        assert sub.remaining == len(kinds) - routed
        assert robot.stats.bad_lines + robot.stats.unknown_acks == len(kinds) - routed
    finally:
        sub.cancel()


def test_first_ack_with_an_empty_pose_is_a_bad_line():
    """The pose cache starts empty: an ack with an empty pose field must not match it (it is malformed)."""
    robot, written = wired_client()
    try:
        sub = robot.submit(Skill("noop"))
        robot.feed(f"{sub.ids[0]}:done:1.000,2.000:\r\n".encode(), 5.0)
        assert sub.results == [None] and sub.remaining == 1
        assert robot.stats.bad_lines == 1 and robot.stats.acks == 0
    finally:
        sub.cancel()


def test_repeated_times_text_gives_the_same_values_as_parsing_it():
    """Acks of one millisecond repeat their times text; the cached floats are those of that text, and a new
    text (or a bad one after a good one) is parsed again."""
    robot, written = wired_client()
    pose = POSES[1]
    try:
        sub = robot.submit(*[Skill("noop", k) for k in range(4)])
        ids = sub.ids
        lines = [encode_ack(Ack(ids[0], Status.DONE, 1.5, 1.5, pose)),
                 encode_ack(Ack(ids[1], Status.DONE, 1.5, 1.5, pose)),
                 encode_ack(Ack(ids[2], Status.DONE, 1.5, 1.5, pose)).replace(b"1.500,1.500", b"1.500,nan"),
                 encode_ack(Ack(ids[3], Status.DONE, 1.5, 2.25, pose))]
        robot.feed(b"".join(lines[:2]), 5.0)
        robot.feed(b"".join(lines[2:]), 6.0)
        assert [r.ack if r else None for r in sub.results] == [
            Ack(ids[0], Status.DONE, 1.5, 1.5, pose), Ack(ids[1], Status.DONE, 1.5, 1.5, pose), None,
            Ack(ids[3], Status.DONE, 1.5, 2.25, pose)]
        assert robot.stats.bad_lines == 1 and sub.remaining == 1
    finally:
        sub.cancel()


def test_fast_path_builds_exactly_the_values_the_constructors_build():
    from aioadept.client import MessageResult

    robot, written = wired_client()
    pose = POSES[1]
    try:
        sub = robot.submit(Skill("noop", 1), Skill("noop", 2))
        a, b = sub.ids
        robot.feed(encode_ack(Ack(a, Status.DONE, 1.0, 2.0, pose)) + encode_ack(Ack(b, Status.DONE, 1.0, 2.0, pose)),
                    7.0)
        got = sub.results[1]
        want = MessageResult(b, "noop", (2,), sub.batch, sub.t_send_s, 7.0, Ack(b, Status.DONE, 1.0, 2.0, pose))
        assert type(got) is MessageResult and type(got.ack) is Ack
        assert got == want and hash(got.ack) == hash(want.ack) and repr(got) == repr(want)
    finally:
        sub.cancel()


def test_acks_out_of_order_reach_their_own_messages():
    """The index of an ack is guessed as the one after the previous ack's; out of order it is searched for."""
    robot, written = wired_client()
    pose = POSES[0]
    try:
        sub = robot.submit(*[Skill("noop", k) for k in range(6)])
        ids = sub.ids
        order = [3, 0, 4, 5, 1, 2]
        lines = [encode_ack(Ack(ids[k], Status.DONE, float(k), float(k), pose)) if k != 5 else
                 encode_ack(Ack.error(ids[k], -610, "out of range", 5.0, 5.0, pose)) for k in order]
        robot.feed(b"".join(lines[:3]), 1.0)
        robot.feed(b"".join(lines[3:]), 2.0)
        assert [r.id for r in sub.results] == list(ids)
        assert [(r.args, r.ack.t_done_s) for r in sub.results] == [((k,), float(k)) for k in range(6)]
        assert [r.ack.status for r in sub.results] == [Status.DONE] * 5 + [Status.ERROR]
        assert [f.result() for f in sub.futures] == sub.results
        assert sub.remaining == 0 and robot.pending_ids == () and robot.stats.acks == 6
    finally:
        sub.cancel()


def test_register_writes_ids_and_lines_and_a_lost_connection_says_what_is_known_done():
    """Registered before the write (the IDs are pending as soon as the bytes exist); fail_all empties the registry
    and tells each batch which messages are acked and which are unresolved."""
    from aioadept.errors import ConnectionLost

    w = Wired(id_start=0xFFFFFFFE)
    sub = w.submit(Skill("noop", 1), Skill("noop", 2), Skill("noop", 3))
    assert w.written[0] == b"fffffffe:noop:1\r\nffffffff:noop:2\r\n00000001:noop:3\r\n"  # 00000000 never issued
    assert w.pending_ids == sub.ids == ("fffffffe", "ffffffff", "00000001")
    sub._waiter = waiter = Box()
    w.feed(encode_ack(Ack("fffffffe", Status.DONE, 1.0, 1.0, POSES[0])), 1.0)
    assert w.pending_ids == ("ffffffff", "00000001") and not waiter.done()
    assert w.reg.fail_all("peer closed") == [sub]
    assert w.pending_ids == () and sub.done() and sub.lost_reason == "peer closed" and waiter.result() == 2
    assert sub.futures[0].result() is sub.results[0]
    for fut, mid in zip(sub.futures[1:], sub.ids[1:], strict=True):
        assert isinstance(fut.error, ConnectionLost) and fut.error.unresolved == (mid,)


def test_a_released_message_s_late_ack_is_counted_not_routed():
    w = Wired()
    sub = w.submit(Skill("noop"))
    assert w.reg.release(sub) and not w.reg.release(sub)  # idempotent
    assert w.pending_ids == () and w.reg.abandoned_ids == sub.ids
    w.feed(encode_ack(Ack(sub.ids[0], Status.DONE, 1.0, 1.0, POSES[0])), 1.0)
    assert sub.results == [None] and w.stats.late_acks == 1 and w.stats.unknown_acks == 0
    w.feed(encode_ack(Ack(sub.ids[0], Status.DONE, 1.0, 1.0, POSES[0])), 2.0)  # a second one is unknown
    assert w.stats.unknown_acks == 1 and w.stats.unexpected[-1][1:] == (
        "unknown_ack", encode_ack(Ack(sub.ids[0], Status.DONE, 1.0, 1.0, POSES[0]))[:-2])
