"""Synthetic focus-loop runs with realistic timing, for trying the analysis and plots without a cell.

:func:`synthetic_recorder` drives a :class:`aioadept.runs.capture.Recorder` through the same observer hooks the
RobotClient and Communicator call, with the message pattern of the paper's ``ufloop``: an ``init_move`` batch, then
per iteration one vision request and one ``set_speed``/``move_rel_tool``/``break`` batch, then the retract batch.
Timing model (all seeded):

- switching durations (eqs. 2-5) are log-normal: robot↔vision around ``switch_median_ms`` (paper: ~1 ms),
  consecutive sends around ``send_median_ms`` (paper: ~0.2 ms);
- each robot increment takes the motion time of ``delta_z_mm`` at ``approach_speed`` plus a Gaussian network and
  scheduling overhead (paper Fig. 11: 5.2 ± 1.0 ms), split between the two directions;
- the server clock is offset from the client clock and ticks in 1 ms steps, like V+ ``TIMER(-3)``;
- sharpness rises towards the focus plane and falls after it, so the loop ends as the paper's does.

This is test and demonstration data, not a model of any particular controller.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from aioadept.bus import Request, Response
from aioadept.runs.capture import Recorder
from aioadept.client import MessageResult, SentMessage
from aioadept.robots import paper_cell
from aioadept.geometry import Pose
from aioadept.protocol import Ack, Status

__all__ = ["synthetic_recorder"]


def _lognormal_ms(rng: np.random.Generator, median_ms: float, shape: float) -> float:
    return float(median_ms * math.exp(shape * rng.standard_normal()))


def synthetic_recorder(*, seed: int = 0, approach_speed: int = 25, delta_z_mm: float = 2.0, n_steps: int = 12,
                       switch_median_ms: float = 0.9, send_median_ms: float = 0.2, switch_shape: float = 0.55,
                       overhead_mean_ms: float = 5.2, overhead_std_ms: float = 1.0,
                       vision_mean_ms: float = 45.0, focus_step: int | None = None,
                       start_loop_s: float = 1000.0,
                       server_offset_s: float = -990.0) -> tuple[Recorder, Mapping[str, Any]]:
    """A recorder filled with one synthetic run of ``n_steps`` approach iterations; returns it and its parameters.

    The sharpness peaks at step ``focus_step`` (default ``n_steps - 1``, so the loop sends ``n_steps`` approach
    batches), then one more vision request sees the first fall and the retract batch follows. Robot increments last
    ``delta_z_mm / (2.5 mm/s * approach_speed) + 100 ms`` (~100-300 ms over the paper's parameter grid).
    """
    rng = np.random.default_rng(seed)
    focus = n_steps - 1 if focus_step is None else focus_step
    t = start_loop_s
    rec = Recorder(clock=lambda: t)
    ids = iter(f"{n:08x}" for n in range(1, 1 << 30))
    batch = 0
    z_mm = 400.0

    def server(t_client: float) -> float:
        return math.floor((t_client + server_offset_s) * 1000.0) / 1000.0  # 1 ms ticks

    def robot_batch(calls: list[tuple[str, tuple]], t0: float, motion_s: float) -> float:
        """Send ``calls`` starting at t0; the last call is the one that waits for the motion. Returns its ack time."""
        nonlocal batch, z_mm
        batch += 1
        ovh_s = max(rng.normal(overhead_mean_ms, overhead_std_ms), 0.5) / 1000.0
        lat_in, lat_out = ovh_s * 0.5, ovh_s * 0.5
        ts = t0
        sends = []
        for k, (skill, args) in enumerate(calls):
            if k:
                ts += _lognormal_ms(rng, send_median_ms, switch_shape) / 1000.0
            sends.append(SentMessage(next(ids), skill, args, batch, ts))
            rec.on_send(sends[-1])
        # Server side: each non-final skill acks at once, the last (break) acks when the motion ends.
        t_srv_first = sends[0].t_send_s + lat_in
        if calls[-1][0] == "break" and calls[-2][0] == "move_rel_tool":
            z_mm -= float(calls[-2][1][2])  # tool z points towards the camera, down in the world
        pose = Pose(350.0, 0.0, z_mm, 0.0, 180.0, 0.0)
        t_move_start = None
        last_recv = t0
        for k, s in enumerate(sends):
            t_in = max(s.t_send_s + lat_in, t_srv_first)
            if k < len(sends) - 1:
                t_start, t_done = t_in, t_in + 0.0003
                if s.skill.startswith("move"):
                    t_move_start = t_in
            else:
                t_start = t_in
                t_done = max(t_in, (t_move_start if t_move_start is not None else t_in) + motion_s)
            ack = Ack(s.id, Status.DONE, server(t_start), server(t_done), pose)
            t_recv = t_done + lat_out + 0.00002 * k
            rec.on_ack(MessageResult(s.id, s.skill, s.args, s.batch, s.t_send_s, t_recv, ack))
            last_recv = max(last_recv, t_recv)
        return last_recv

    def motion_time_s(dz_mm: float) -> float:
        speed_mm_s = 2.5 * max(approach_speed, 1)  # ~250 mm/s at 100 %, scaled like V+ SPEED
        return abs(dz_mm) / speed_mm_s + 0.1  # + acceleration, deceleration and settling

    # init_move: one cmdexec of four motions (each its own batch of motion + break)
    for joints in (paper_cell.HOME_JOINTS_DEG, paper_cell.REL_JOINTS_DEG):
        t = robot_batch([("move_joints", tuple(float(j) for j in joints)), ("break", ())], t, 0.8) + 0.0005

    sharp_peak = 60.0
    step = 0
    while True:
        rec.mark("iteration", step, t_s=t)
        t += _lognormal_ms(rng, switch_median_ms, switch_shape) / 1000.0  # eq. 2
        vid = f"v{next(ids)[1:]}"
        t_vreq = t
        rec.on_request(Request(vid, "VisionRequest", {"t_request": 1.7e9 + t}, t_vreq))
        t += max(rng.normal(vision_mean_ms, vision_mean_ms * 0.15), 5.0) / 1000.0
        width = (focus + 2) / 2.0  # wide enough that the rise beats the noise from the first step
        s = sharp_peak * math.exp(-((step - focus) / width) ** 2) + 5.0 + rng.normal(0, 0.05)
        rec.on_response(Response(vid, "VisionResponse",
                                  {"sharpness": s, "frame_t": 1.7e9 + t - 0.02,
                                   "proc_time_ms": float(rng.normal(12.0, 1.5))}, t_vreq, t))
        if step > focus:  # the first fall: leave the loop, retract one step
            break
        t += _lognormal_ms(rng, switch_median_ms, switch_shape) / 1000.0  # eq. 3
        t = robot_batch([("set_speed", (approach_speed,)), ("move_rel_tool", (0.0, 0.0, delta_z_mm, 0.0, 0.0, 0.0)),
                         ("break", ())], t, motion_time_s(delta_z_mm))
        step += 1
    rec.mark("retract", step + 1, t_s=t)
    t += 0.001
    robot_batch([("set_speed", (approach_speed,)), ("move_rel_tool", (0.0, 0.0, -delta_z_mm, 0.0, 0.0, 0.0)),
                 ("break", ())], t, motion_time_s(delta_z_mm))
    return rec, {"approach_speed": approach_speed, "delta_z_mm": delta_z_mm, "seed": seed, "synthetic": True}
