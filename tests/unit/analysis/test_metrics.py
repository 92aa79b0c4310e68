"""The paper's eqs. 1-5 on a small hand-made log, with extra batches, an incomplete iteration and a retract."""

from __future__ import annotations

import pytest

from aioadept.analysis.metrics import describe, find_iterations, iterations_of_run, quantity_values
from aioadept.runs.capture import Mark, RobotRecord, Run, VisionRecord

APPROACH = (0.0, 0.0, 2.0, 0.0, 0.0, 0.0)
RETRACT = (0.0, 0.0, -2.0, 0.0, 0.0, 0.0)


class Log:
    """Builds records: client times in s on one clock, server times on another (offset ~ -990 s)."""

    def __init__(self) -> None:
        self.robot: list[RobotRecord] = []
        self.vision: list[VisionRecord] = []
        self.marks: list[Mark] = []

    def msg(self, batch: int, skill: str, t_send: float, t_recv: float | None, t_start: float | None,
            t_done: float | None, args: tuple = (), status: str | None = "done") -> None:
        n = len(self.robot)
        self.robot.append(RobotRecord(n, f"{n:08x}", skill, args, batch, t_send, t_recv, t_start, t_done,
                                      status if t_recv is not None else None))

    def approach(self, batch: int, t_ss: float, t_mrt: float, t_b: float, t_b_recv: float | None,
                 s_ss: float, s_b: float, s_b_done: float, args: tuple = APPROACH) -> None:
        self.msg(batch, "set_speed", t_ss, t_ss + 0.001, s_ss, s_ss, (25,))
        self.msg(batch, "move_rel_tool", t_mrt, t_mrt + 0.0015, s_ss + 0.001, s_ss + 0.001, args)
        self.msg(batch, "break", t_b, t_b_recv, s_b if t_b_recv else None, s_b_done if t_b_recv else None)

    def vis(self, t_send: float, t_recv: float | None, sharpness: float | None = None, error: str | None = None):
        n = len(self.vision)
        self.vision.append(VisionRecord(n, f"v{n:07d}", "VisionRequest", t_send, t_recv,
                                        "VisionResponse" if t_recv else None, sharpness, error=error))


def paper_log(*, with_marks: bool = True) -> Log:
    log = Log()
    # init_move: a batch of other skills before the first vision request (ignored)
    log.msg(1, "move_joints", 0.000, 0.005, 9.0, 9.0, (0, -90, 180, 0, 90, 0))
    log.msg(1, "break", 0.0002, 0.900, 9.0, 9.9)
    # iteration 0
    log.vis(1.000, 1.050, 10.0)
    log.approach(2, 1.051, 1.0512, 1.0515, 1.210, s_ss=10.000, s_b=10.002, s_b_done=10.150)
    # iteration 1
    log.vis(1.2115, 1.260, 11.0)
    log.approach(3, 1.2625, 1.2630, 1.2634, 1.420, s_ss=10.200, s_b=10.203, s_b_done=10.350)
    log.msg(4, "here", 1.421, 1.4215, 10.36, 10.36)  # a stray batch between iterations: not an iteration
    # iteration 2: the break is never acked (connection lost) -> incomplete
    log.vis(1.425, 1.470, 12.0)
    log.approach(5, 1.471, 1.4712, 1.4714, None, s_ss=10.400, s_b=10.401, s_b_done=0.0)
    # iteration 3: complete, but its predecessor is not -> no tau r->v
    log.vis(1.600, 1.650, 13.0)
    log.approach(6, 1.651, 1.6513, 1.6517, 1.800, s_ss=10.600, s_b=10.601, s_b_done=10.750)
    # the fall, then the retract batch (same three skills, other direction)
    log.vis(1.801, 1.850, 12.5)
    if with_marks:
        log.marks.append(Mark(0, 1.8505, "retract", 5))
    log.approach(7, 1.851, 1.8512, 1.8515, 2.0, s_ss=10.800, s_b=10.801, s_b_done=10.95, args=RETRACT)
    return log


def _iters(log: Log):
    return find_iterations(log.robot, log.vision, marks=log.marks, run="r1", parameters={"appr_speed": 25})


@pytest.mark.parametrize("with_marks", [True, False])
def test_iterations_are_found_and_extras_ignored(with_marks: bool) -> None:
    its = _iters(paper_log(with_marks=with_marks))
    assert [(it.index, it.batch, it.complete) for it in its] == [(0, 2, True), (1, 3, True), (2, 5, False),
                                                                (3, 6, True)]
    assert [it.sharpness for it in its] == [10.0, 11.0, 12.0, 13.0]
    assert all(it.run == "r1" and it.parameters == {"appr_speed": 25} for it in its)


def test_taus_match_hand_computed_values() -> None:
    i0, i1, i2, i3 = _iters(paper_log())
    # eq. 1: (1.210 - 1.051) - (10.002 - 10.000) = 0.157 s
    assert i0.tau_r_ms == pytest.approx(157.0)
    # (1.420 - 1.2625) - (10.203 - 10.200) = 0.1545 s
    assert i1.tau_r_ms == pytest.approx(154.5)
    assert i3.tau_r_ms == pytest.approx((1.800 - 1.651 - 0.001) * 1000)
    # eq. 2: the first iteration has none; i1: 1.2115 - 1.210; i3: predecessor incomplete -> none
    assert i0.tau_r_to_v_ms is None
    assert i1.tau_r_to_v_ms == pytest.approx(1.5)
    assert i3.tau_r_to_v_ms is None
    # eq. 3
    assert i0.tau_v_to_r_ms == pytest.approx(1.0)
    assert i1.tau_v_to_r_ms == pytest.approx(2.5)
    assert i3.tau_v_to_r_ms == pytest.approx(1.0)
    # eqs. 4 and 5
    assert (i0.tau_ss_to_mrt_ms, i0.tau_mrt_to_b_ms) == (pytest.approx(0.2), pytest.approx(0.3))
    assert (i1.tau_ss_to_mrt_ms, i1.tau_mrt_to_b_ms) == (pytest.approx(0.5), pytest.approx(0.4))
    # overhead: client wait minus server busy time, (1.210 - 1.051) - (10.150 - 10.000)
    assert i0.tau_overhead_ms == pytest.approx(9.0)
    # the incomplete iteration has no taus at all
    assert (i2.tau_r_ms, i2.tau_v_to_r_ms, i2.tau_ss_to_mrt_ms) == (None, None, None)


def test_quantity_values_skip_incomplete_and_undefined() -> None:
    its = _iters(paper_log())
    assert quantity_values(its, "tau_r_to_v_ms").tolist() == pytest.approx([1.5])
    assert quantity_values(its, "tau_v_to_r_ms").tolist() == pytest.approx([1.0, 2.5, 1.0])


def test_vision_error_makes_the_iteration_incomplete() -> None:
    log = Log()
    log.vis(1.0, 1.05, error="no object found")
    log.approach(1, 1.051, 1.0512, 1.0515, 1.21, s_ss=10.0, s_b=10.002, s_b_done=10.15)
    (it,) = _iters(log)
    assert not it.complete and it.tau_r_ms is None


def test_error_ack_makes_the_iteration_incomplete() -> None:
    log = Log()
    log.vis(1.0, 1.05, 3.0)
    log.approach(1, 1.051, 1.0512, 1.0515, 1.21, s_ss=10.0, s_b=10.002, s_b_done=10.15)
    log.robot[1] = RobotRecord(1, "x", "move_rel_tool", APPROACH, 1, 1.0512, 1.06, 10.0, 10.0, "error")
    (it,) = _iters(log)
    assert not it.complete


def test_a_batch_before_the_first_request_is_not_an_iteration() -> None:
    log = Log()
    log.approach(1, 0.5, 0.5001, 0.5002, 0.7, s_ss=9.0, s_b=9.001, s_b_done=9.1)
    log.vis(1.0, 1.05, 3.0)  # the last request: no approach batch after it
    assert _iters(log) == ()


def test_cmdexec_split_batches_count_as_one_increment() -> None:
    # cmdexec(SetSpeed, MoveToolZ): set_speed in one batch, move_rel_tool + break in the next.
    log = Log()
    log.vis(1.0, 1.05, 3.0)
    log.approach(1, 1.051, 1.0535, 1.0535, 1.21, s_ss=10.0, s_b=10.003, s_b_done=10.15)
    log.robot[1] = RobotRecord(1, "m", "move_rel_tool", APPROACH, 2, 1.0535, 1.055, 10.003, 10.003, "done")
    log.robot[2] = RobotRecord(2, "b", "break", (), 2, 1.0535, 1.21, 10.003, 10.15, "done")
    (it,) = _iters(log)
    assert it.complete and it.tau_ss_to_mrt_ms == pytest.approx(2.5) and it.tau_mrt_to_b_ms == 0.0
    assert it.tau_r_ms == pytest.approx((1.21 - 1.051 - 0.003) * 1000)
    # a lone set_speed followed by something else is no increment
    log2 = Log()
    log2.vis(1.0, 1.05, 3.0)
    log2.msg(1, "set_speed", 1.051, 1.052, 10.0, 10.0, (25,))
    log2.msg(2, "move_to", 1.053, 1.2, 10.0, 10.1, (1, 2, 3, 4, 5, 6))
    assert _iters(log2) == ()


def test_iterations_of_run_uses_name_and_parameters() -> None:
    log = paper_log()
    run = Run(tuple(log.robot), tuple(log.vision), tuple(log.marks), {"parameters": {"delta_z_mm": 2.0},
                                                                      "name": "grid/001"})
    its = iterations_of_run(run)
    assert len(its) == 4 and its[0].run == "grid/001" and its[0].parameters == {"delta_z_mm": 2.0}


def test_describe_hand_computed() -> None:
    s = describe([1.0, 2.0, 3.0, 4.0])
    assert (s.n, s.mean_ms, s.min_ms, s.median_ms, s.max_ms) == (4, 2.5, 1.0, 2.5, 4.0)
    assert s.std_ms == pytest.approx((5 / 3) ** 0.5)  # sample std: sum of squares 5, n - 1 = 3
    assert s.p99_ms == pytest.approx(3.97)  # linear interpolation at rank 0.99 * 3 = 2.97
    one = describe([7.0])
    assert (one.n, one.mean_ms, one.std_ms, one.p99_ms) == (1, 7.0, None, 7.0)
    assert describe([]).n == 0 and describe([]).mean_ms is None
