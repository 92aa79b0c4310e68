"""The paper's timing metrics (Semeniuta & Falkman 2019, "Time measurements", eqs. 1-5), as pure functions.

Input: the records of a run (:class:`aioadept.runs.capture.Run`, or any objects with the same attributes). Output:
one :class:`Iteration` per vision request of the approach loop, with its timestamps and tau values in ms.

An iteration ``i`` of the paper's ``ufloop`` is one vision request followed by one robot batch of exactly the three
messages ``set_speed``, ``move_rel_tool``, ``break`` (one ``move_tool_z`` sent with ``cmdexec_joined``)::

    tau_r       = (t_b_rresp - t_ss_rreq) - (t_b_rstart - t_ss_rstart)      (1)
    tau_r->v_i  = t_vreq_i - t_b_rresp_{i-1}                                 (2)  i >= 1
    tau_v->r_i  = t_ss_rreq_i - t_vresp_i                                    (3)
    tau_ss->mrt = t_mrt_rreq - t_ss_rreq                                     (4)
    tau_mrt->b  = t_b_rreq - t_mrt_rreq                                      (5)

``rreq``/``rresp``/``vreq``/``vresp`` are client loop-clock times of send and receive, ``rstart``/``rdone`` the
server's own clock in the acks; eq. 1 subtracts server durations from client durations, so the two clocks never
mix. Everything else in a run (``init_move``, other batches, the final retract after the sharpness fell) is not
an iteration and is skipped. See ``docs/analysis.md``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

__all__ = [
    "APPROACH_SKILLS", "QUANTITIES", "Iteration", "Quantity", "Stats", "describe", "find_iterations",
    "iterations_of_run", "quantity_values",
]

APPROACH_SKILLS: tuple[str, str, str] = ("set_speed", "move_rel_tool", "break")
"""The skill sequence of one approach batch (``move_tool_z``)."""


@dataclass(frozen=True, slots=True)
class Quantity:
    """One metric: its column name, the paper's equation number and figure, and a plot label."""

    name: str
    symbol: str
    label: str
    equation: int | None
    figure: str | None
    family: str  # "normal" or "lognormal": the distribution the paper fits


QUANTITIES: tuple[Quantity, ...] = (
    Quantity("tau_r_ms", "τ_r", "travel time of a motion increment", 1, "11", "normal"),
    Quantity("tau_r_to_v_ms", "τ(r→v)", "switching robot → vision", 2, "12A", "lognormal"),
    Quantity("tau_v_to_r_ms", "τ(v→r)", "switching vision → robot", 3, "12B", "lognormal"),
    Quantity("tau_ss_to_mrt_ms", "τ(ss→mrt)", "send set_speed → send move_rel_tool", 4, "13A", "lognormal"),
    Quantity("tau_mrt_to_b_ms", "τ(mrt→b)", "send move_rel_tool → send break", 5, "13B", "lognormal"),
    # Not in the paper: client wait minus the server's whole busy time (set_speed start to break done), i.e. the
    # communication and scheduling overhead of one increment. It equals eq. 1 when the server stamps break's start
    # at the end of the motion; see docs/analysis.md.
    Quantity("tau_overhead_ms", "τ_ovh", "client wait − server busy time", None, None, "normal"),
)
QUANTITY_BY_NAME = {q.name: q for q in QUANTITIES}


@dataclass(frozen=True, slots=True)
class Iteration:
    """One approach iteration: a vision request and the robot batch after it. Times in s, taus in ms.

    ``complete`` is False when the vision request was not answered (or answered with an error) or a robot message
    of the batch was not acked with ``done``; its taus are then None. ``tau_r_to_v_ms`` also needs iteration
    ``index - 1`` of the same run complete. ``index`` counts vision requests of the approach from 0.
    """

    run: str
    index: int
    vision_id: str
    batch: int | None
    t_vreq_s: float | None
    t_vresp_s: float | None
    t_ss_rreq_s: float | None = None
    t_mrt_rreq_s: float | None = None
    t_b_rreq_s: float | None = None
    t_b_rresp_s: float | None = None
    t_ss_rstart_s: float | None = None
    t_b_rstart_s: float | None = None
    t_b_rdone_s: float | None = None
    sharpness: float | None = None
    complete: bool = False
    tau_r_ms: float | None = None
    tau_r_to_v_ms: float | None = None
    tau_v_to_r_ms: float | None = None
    tau_ss_to_mrt_ms: float | None = None
    tau_mrt_to_b_ms: float | None = None
    tau_overhead_ms: float | None = None
    parameters: Mapping[str, Any] = field(default_factory=dict)

    def tau(self, name: str) -> float | None:
        return getattr(self, name)


def _ok(r: Any) -> bool:
    status = getattr(r, "status", None)
    return (r.t_recv_s is not None and r.t_send_s is not None and getattr(r, "t_start_s", None) is not None
            and (status is None or str(getattr(status, "value", status)) == "done"))


def _batches(robot: Sequence[Any]) -> list[list[Any]]:
    """Robot records grouped by ``batch``, each group in send order, groups ordered by their first send."""
    groups: dict[Any, list[Any]] = {}
    for r in robot:
        if r.t_send_s is None:
            continue
        key = r.batch if r.batch is not None else ("solo", r.id)  # no batch id: a batch of one
        groups.setdefault(key, []).append(r)
    out = [sorted(g, key=lambda r: r.t_send_s) for g in groups.values()]
    return sorted(out, key=lambda g: g[0].t_send_s)


def _approach_groups(groups: Sequence[list[Any]], skills: Sequence[str]) -> list[list[Any]]:
    """The increments: batches whose skills are exactly ``skills`` or, written by ``cmdexec`` instead of
    ``cmdexec_joined`` (``set_speed`` acked before ``move_rel_tool`` + ``break`` are written), consecutive batches
    that together are."""
    want = tuple(skills)
    out: list[list[Any]] = []
    i = 0
    while i < len(groups):
        acc = list(groups[i])
        j = i + 1
        while len(acc) < len(want) and j < len(groups) and tuple(r.skill for r in acc) == want[:len(acc)]:
            acc += groups[j]
            j += 1
        if tuple(r.skill for r in acc) == want:
            out.append(acc)
            i = j
        else:
            i += 1
    return out


def _z_step(group: Sequence[Any]) -> float:
    args = tuple(group[1].args)
    return float(args[2]) if len(args) > 2 else 0.0


def find_iterations(robot: Sequence[Any], vision: Sequence[Any], *, marks: Sequence[Any] = (), run: str = "run",
                    parameters: Mapping[str, Any] | None = None,
                    skills: Sequence[str] = APPROACH_SKILLS) -> tuple[Iteration, ...]:
    """Reconstruct the approach iterations of one run and compute their taus (ms).

    Pairing: each vision request (in send order) owns the first ``skills`` batch sent after it and before the next
    vision request (``skills`` split over consecutive batches, as ``cmdexec`` sends them, count as one). The final
    retract (the same three skills, the other z direction) is not an iteration: it is recognised as a batch sent
    after a mark named ``"retract"`` when the run has one (``apps.paper.ufloop`` writes it), otherwise as a batch
    whose ``move_rel_tool`` z step has the sign opposite to the run's first approach batch. Vision requests with no
    approach batch after them (the last one, or one that failed) are dropped.
    """
    params = dict(parameters or {})
    reqs = sorted((v for v in vision if v.t_send_s is not None), key=lambda v: v.t_send_s)
    groups = _approach_groups(_batches(robot), skills)
    retract_marks = [m.t_s for m in marks if m.name == "retract"]
    t_retract = min(retract_marks) if retract_marks else math.inf
    groups = [g for g in groups if g[0].t_send_s < t_retract]
    if not retract_marks and groups:
        # Without marks, the sign of the z step tells the approach from the retract.
        first_sign = None
        for v in reqs:
            after = [g for g in groups if g[0].t_send_s >= v.t_send_s]
            if after:
                first_sign = math.copysign(1.0, _z_step(after[0]))
                break
        if first_sign is not None:
            groups = [g for g in groups if math.copysign(1.0, _z_step(g)) == first_sign]

    pairs: list[tuple[Any, list[Any]]] = []
    gi = 0
    for k, v in enumerate(reqs):
        t_next = reqs[k + 1].t_send_s if k + 1 < len(reqs) else math.inf
        while gi < len(groups) and groups[gi][0].t_send_s < v.t_send_s:
            gi += 1  # batches before this request (init_move, stray ones) belong to no iteration
        if gi < len(groups) and groups[gi][0].t_send_s < t_next:
            pairs.append((v, groups[gi]))
            gi += 1
    # ``index`` counts requests from the first one that owns a batch, so a request in between that owns none
    # (it failed and was retried) leaves a gap and the next iteration gets no tau_r->v: its previous break ack is
    # not the one right before it.
    out: list[Iteration] = []
    req_pos = {id(v): n for n, v in enumerate(reqs)}
    first_pos = req_pos[id(pairs[0][0])] if pairs else 0
    prev: Iteration | None = None
    for v, (ss, mrt, b) in pairs:
        index = req_pos[id(v)] - first_pos
        vis_ok = v.t_recv_s is not None and not getattr(v, "error", None)
        complete = vis_ok and all(_ok(r) for r in (ss, mrt, b))
        it = Iteration(
            run=run, index=index, vision_id=v.id, batch=ss.batch, t_vreq_s=v.t_send_s, t_vresp_s=v.t_recv_s,
            t_ss_rreq_s=ss.t_send_s, t_mrt_rreq_s=mrt.t_send_s, t_b_rreq_s=b.t_send_s, t_b_rresp_s=b.t_recv_s,
            t_ss_rstart_s=ss.t_start_s, t_b_rstart_s=b.t_start_s, t_b_rdone_s=b.t_done_s,
            sharpness=getattr(v, "sharpness", None), complete=complete, parameters=params,
        )
        if complete:
            it = _with_taus(it, prev if prev is not None and prev.index == index - 1 else None)
        out.append(it)
        prev = it
    return tuple(out)


def _ms(seconds: float) -> float:
    return seconds * 1000.0


def _with_taus(it: Iteration, prev: Iteration | None) -> Iteration:
    assert it.t_b_rresp_s is not None and it.t_ss_rreq_s is not None and it.t_vresp_s is not None
    tau_r = _ms((it.t_b_rresp_s - it.t_ss_rreq_s) - (it.t_b_rstart_s - it.t_ss_rstart_s))
    ovh = (_ms((it.t_b_rresp_s - it.t_ss_rreq_s) - (it.t_b_rdone_s - it.t_ss_rstart_s))
           if it.t_b_rdone_s is not None else None)
    r_to_v = (_ms(it.t_vreq_s - prev.t_b_rresp_s)
              if prev is not None and prev.complete and prev.t_b_rresp_s is not None else None)
    return replace(
        it, tau_r_ms=tau_r, tau_r_to_v_ms=r_to_v, tau_v_to_r_ms=_ms(it.t_ss_rreq_s - it.t_vresp_s),
        tau_ss_to_mrt_ms=_ms(it.t_mrt_rreq_s - it.t_ss_rreq_s), tau_mrt_to_b_ms=_ms(it.t_b_rreq_s - it.t_mrt_rreq_s),
        tau_overhead_ms=ovh,
    )


def iterations_of_run(run: Any, *, skills: Sequence[str] = APPROACH_SKILLS) -> tuple[Iteration, ...]:
    """:func:`find_iterations` on a :class:`aioadept.runs.capture.Run` (its name and parameters go into each row)."""
    return find_iterations(run.robot, run.vision, marks=getattr(run, "marks", ()), run=run.name,
                           parameters=run.parameters, skills=skills)


def quantity_values(iterations: Iterable[Iteration], name: str) -> np.ndarray:
    """The defined values (ms) of one quantity over complete iterations, in order, as a float array."""
    vals = [it.tau(name) for it in iterations if it.complete]
    return np.asarray([v for v in vals if v is not None], dtype=float)


@dataclass(frozen=True, slots=True)
class Stats:
    """Descriptive statistics of one quantity, in ms. ``std_ms`` is the sample std (ddof=1), None when n < 2."""

    n: int
    mean_ms: float | None
    std_ms: float | None
    min_ms: float | None
    median_ms: float | None
    p99_ms: float | None
    max_ms: float | None

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__slots__}


def describe(values_ms: Sequence[float] | np.ndarray) -> Stats:
    """n, mean, std (ddof=1), min, median, 99th percentile (linear interpolation), max; None fields when empty."""
    x = np.asarray(values_ms, dtype=float)
    if x.size == 0:
        return Stats(0, None, None, None, None, None, None)
    return Stats(int(x.size), float(x.mean()), float(x.std(ddof=1)) if x.size > 1 else None, float(x.min()),
                 float(np.median(x)), float(np.percentile(x, 99)), float(x.max()))
