"""The processing node (the paper's ImProcNode): a vision request in, the frame(s) for its time through the graph,
a response out.

Where it sits: :class:`aioadept.bus.responder.Responder` receives ``VisionRequest`` events and calls
:meth:`VisionNode.handle` on the event loop; the node picks the frame for ``t_request`` from the
:class:`Acquisition` ring buffers (policy ``nearest``: at once; ``after``: awaited on the loop, woken by the grabbing
thread, no thread blocked), runs the computational graph, and returns the response attributes of
docs/interfaces.md:

- ``sharpness`` (DOUBLE), ``frame_t`` (DOUBLE, epoch s of the frame), ``proc_time_ms`` (DOUBLE, the graph run);
- ``error`` (STRING) instead of ``sharpness`` when it failed: no frame for that time, no object found, a frame
  whose robot pose is older than ``max_state_age_s`` (the state stream went silent: the virtual camera would show a
  frozen pose, and a sharpness from it would be a wrong answer), a ``t_request`` that is not a finite number;
- also ``camera`` (STRING), ``frame_seq`` (INT) and ``frame_age_ms`` (DOUBLE, ``t_request - frame_t``).

A request with attribute ``camera`` is answered from that camera; without it from the first camera, and when the
node has several cameras the others' results are added as ``sharpness.<camera>`` / ``frame_t.<camera>`` /
``error.<camera>`` (one frame set per request, as FxIS grabs several cameras together).

Where the graph runs (``graph_thread``): ``"never"`` on the loop thread, ``"always"`` in the node's one worker
thread, ``"auto"`` (default) on the loop while the measured cost of a graph run (an exponentially weighted moving
average) is at most ``inline_max_ms``, else in the worker. A run on the loop saves the two thread
wake-ups of a hand-off (loop -> worker -> loop: 0.1-0.5 ms on a loaded 2-core machine, against ~10 us for the no-op
graph and ~2 ms for the sharpness graph); the worker keeps the loop free (signals, cached answers to repeated ids)
during runs long enough for that to matter. The Responder serves one request at a time either way. Saving the frame
(``--save-frames``: a PNG, ~10 ms) happens after the answer, in a writer thread of its own.

:class:`NodeResponder` is the Responder the ``aioadept vision`` command uses: a request the node can answer without
waiting (policy ``nearest``, the graph on the loop, nothing else in progress) is answered right in the socket
callback, like a plain handler; any other goes through the Responder's worker task and :meth:`VisionNode.handle`.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import os
import queue
import threading
import time
from collections.abc import Awaitable, Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Literal

from aioadept.bus.responder import Responder
from aioadept.bus.messages import VISION_REQUEST
from aioadept.errors import BadRequest, VisionError
from aioadept.vision.acquisition import DEFAULT_POLICY, Acquisition, Policy
from aioadept.vision.graph import CompGraph
from aioadept.vision.sharpness import measure, sharpness_graph
from aioadept.vision.sources import Frame, FrameRecorder

log = logging.getLogger(__name__)

GraphThread = Literal["auto", "always", "never"]
GRAPH_THREAD_MODES: tuple[str, ...] = ("auto", "always", "never")


DEFAULT_MAX_FRAME_AGE_S = 0.1
"""Policy ``nearest``: the oldest frame (its exposure start, s before ``t_request``) the node answers from; older is
an error. 1.5 frame periods at 15 fps: the nearest frame of a healthy free-running camera is always younger."""

DEFAULT_MAX_STATE_AGE_S = 0.5
"""Oldest robot pose (s behind the frame) the node answers from: 50 periods of the sim's 100 Hz stream, far above
its jitter on a loaded machine, short against the time a focus step takes to move."""


SAVE_NICE = 10
"""Nice value of the node's frame-writer thread (``--save-frames``): it yields the cores to serving."""


def noop_graph() -> CompGraph:
    """A one-function graph answering ``sharpness = 0.0`` without looking at the image: for latency benchmarks."""
    return CompGraph({"noop": lambda image: 0.0}, {"noop": ("image", "sharpness")}, name="noop")


class VisionNode:
    """Turns a request's attributes into response attributes; see the module docstring.

    ``graph`` has free token ``image`` and output ``sharpness`` (default: :func:`sharpness_graph`). ``timeout_s``
    bounds the wait for a frame under policy ``after``. ``recorder`` saves every frame the node serves, in a writer thread of its own (off the response path).
    ``graph_thread`` / ``inline_max_ms``: where :meth:`handle` runs the graph (module docstring); ``cost_ms`` is the
    moving average it decides on (None before the first run, which under ``auto`` goes to the worker), and
    ``inline_runs`` / ``thread_runs`` count the graph runs made on the loop / in the worker by the handlers. Owns
    one worker thread (created on first use, joined by :meth:`close`). ``max_state_age_s`` (default
    :data:`DEFAULT_MAX_STATE_AGE_S`; ``math.inf``: no check): a frame stamped with a ``pose_age_s`` above it (the virtual
    camera, when the robot state stream has been silent that long) is answered with an ``error``, never measured;
    ``stale`` counts those answers.
    """

    COST_EWMA_ALPHA = 0.2
    """Weight of the newest run in ``cost_ms``: one slow outlier (a page fault, a preempted run) moves the average by
    a fifth, and a few normal runs bring it back."""

    def __init__(self, acquisition: Acquisition, graph: CompGraph | None = None, *, policy: Policy = DEFAULT_POLICY,
                 timeout_s: float = 1.0, recorder: FrameRecorder | None = None, graph_thread: GraphThread = "auto",
                 inline_max_ms: float = 5.0, max_state_age_s: float = DEFAULT_MAX_STATE_AGE_S,
                 max_frame_age_s: float = DEFAULT_MAX_FRAME_AGE_S) -> None:
        if isinstance(max_frame_age_s, bool) or not (isinstance(max_frame_age_s, (int, float))
                                                     and max_frame_age_s > 0):
            raise ValueError(f"max_frame_age_s must be > 0 (inf: no check), got {max_frame_age_s!r}")
        self.max_frame_age_s = float(max_frame_age_s)
        if isinstance(max_state_age_s, bool) or not (isinstance(max_state_age_s, (int, float))
                                                     and max_state_age_s > 0):  # NaN fails too
            raise ValueError(f"max_state_age_s must be > 0 (inf: no check), got {max_state_age_s!r}")
        self.max_state_age_s = float(max_state_age_s)
        self.stale = 0
        if graph_thread not in GRAPH_THREAD_MODES:
            raise ValueError(f"graph_thread must be one of {GRAPH_THREAD_MODES}, got {graph_thread!r}")
        if inline_max_ms < 0:
            raise ValueError("inline_max_ms must be >= 0")
        self.acquisition = acquisition
        self.graph = graph if graph is not None else sharpness_graph()
        self.policy = policy
        self.timeout_s = timeout_s
        self.recorder = recorder
        self.graph_thread = graph_thread
        self.inline_max_ms = inline_max_ms
        self.cost_ms: float | None = None
        self.inline_runs = 0
        self.thread_runs = 0
        self.served = 0
        self.failed = 0
        self._executor: ThreadPoolExecutor | None = None
        self._active = 0  # handle() calls in progress (awaiting a frame or the worker)
        self._save_queue: queue.Queue[Frame | None] | None = None
        self._save_thread: threading.Thread | None = None

    # ------------------------------------------------------------------------------------------ sync core
    def process(self, event_type: str, event_id: str | None, attributes: Mapping[str, Any]) -> dict[str, Any]:
        """Answer one request (blocking: may wait for a frame and runs the graph), and log it."""
        out = self._serve(attributes)
        self._log(event_type, event_id, attributes, out)
        return out

    def _serve(self, attributes: Mapping[str, Any], *, on_loop: bool = False) -> dict[str, Any]:
        try:
            t_request, cameras, deadline = self._request(attributes)
        except BadRequest as exc:
            return self._count({"error": str(exc)})
        out: dict[str, Any] = {}
        for i, cid in enumerate(cameras):
            try:
                frame = self.acquisition.frame_at(t_request, camera_id=cid, policy=self.policy,
                                                  timeout_s=max(0.0, deadline - time.monotonic()))
            except VisionError as exc:
                result = {"error": str(exc), "camera": cid}
            else:
                result = self._refuse_stale(frame, t_request)
                if result is None:
                    self.inline_runs += on_loop
                    result = self._measure(frame, t_request, attributes)
            self._merge(out, i, cid, result)
        return self._count(out)

    async def _serve_async(self, attributes: Mapping[str, Any]) -> dict[str, Any]:
        """:meth:`_serve` on the loop: the frame wait is awaited, the graph runs where :meth:`runs_inline` says."""
        try:
            t_request, cameras, deadline = self._request(attributes)
        except BadRequest as exc:
            return self._count({"error": str(exc)})
        out: dict[str, Any] = {}
        for i, cid in enumerate(cameras):
            try:
                frame = await self.acquisition.frame_at_async(t_request, camera_id=cid, policy=self.policy,
                                                              timeout_s=max(0.0, deadline - time.monotonic()))
            except VisionError as exc:
                result = {"error": str(exc), "camera": cid}
            else:
                stale = self._refuse_stale(frame, t_request)
                if stale is not None:
                    result = stale
                elif self.runs_inline():
                    self.inline_runs += 1
                    result = self._measure(frame, t_request, attributes)
                else:
                    self.thread_runs += 1
                    if self._executor is None:
                        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vision-node")
                    result = await asyncio.get_running_loop().run_in_executor(
                        self._executor, self._measure, frame, t_request, attributes)
            self._merge(out, i, cid, result)
        return self._count(out)

    def _request(self, attributes: Mapping[str, Any]) -> tuple[float, list[str], float]:
        t_request = attributes.get("t_request", None)
        if t_request is None:
            t_request = time.time()
        elif isinstance(t_request, bool) or not isinstance(t_request, (int, float)) or not math.isfinite(t_request):
            shown = repr(t_request)
            raise BadRequest("bad request: t_request must be a finite number (epoch s), got "
                             f"{shown if len(shown) <= 40 else shown[:37] + '...'}")
        t_request = float(t_request)
        camera = attributes.get("camera")
        cameras = [str(camera)] if camera else list(self.acquisition.camera_ids)
        return t_request, cameras, time.monotonic() + self.timeout_s

    @staticmethod
    def _merge(out: dict[str, Any], i: int, cid: str, result: Mapping[str, Any]) -> None:
        if i == 0:
            out.update(result)
        else:
            for key in ("sharpness", "frame_t", "error"):
                if key in result:
                    out[f"{key}.{cid}"] = result[key]

    def _refuse_stale(self, frame: Frame, t_request: float) -> dict[str, Any] | None:
        """The error result for a frame rendered from a robot pose older than ``max_state_age_s``, or (policy
        ``nearest``) exposed more than ``max_frame_age_s`` before the request; else None."""
        frame_age = t_request - frame.t_s
        if frame_age > self.max_frame_age_s:
            self.stale += 1
            return {"error": f"stale frame: exposed {frame_age * 1e3:.1f} ms before the request (limit "
                             f"{self.max_frame_age_s * 1e3:g} ms)", **self._frame_attrs(frame, t_request)}
        age = frame.pose_age_s
        if age is None or age <= self.max_state_age_s:
            return None
        self.stale += 1
        if math.isinf(age):
            why = "no robot state received yet"
        else:
            why = f"robot state stream silent for {age:.2f} s"
        return {"error": f"stale robot state: {why} at the frame's time (limit {self.max_state_age_s:g} s); the "
                         "tool pose is unknown, so no sharpness is measured", **self._frame_attrs(frame, t_request)}

    @staticmethod
    def _frame_attrs(frame: Frame, t_request: float) -> dict[str, Any]:
        """Which frame answered and when it was exposed (docs/interfaces.md)."""
        attrs: dict[str, Any] = {
            "camera": frame.camera_id, "frame_t": frame.t_s, "frame_seq": int(frame.seq),
            "frame_age_ms": (t_request - frame.t_s) * 1e3, "t_exposure_start": frame.t_s,
            "exposure_ms": frame.exposure_s * 1e3, "readout_ms": frame.readout_s * 1e3,
        }
        if frame.t_trigger is not None:
            attrs["t_trigger"] = frame.t_trigger
        return attrs

    def _count(self, out: dict[str, Any]) -> dict[str, Any]:
        if "error" in out:
            self.failed += 1
        self.served += 1
        return out

    def runs_inline(self) -> bool:
        """Whether :meth:`handle` runs the next graph on the loop thread (``graph_thread`` and ``cost_ms``)."""
        if self.graph_thread == "auto":
            return self.cost_ms is not None and self.cost_ms <= self.inline_max_ms
        return self.graph_thread == "never"

    def _log(self, event_type: str, event_id: str | None, attributes: Mapping[str, Any],
             out: Mapping[str, Any]) -> None:
        if not log.isEnabledFor(logging.INFO):
            return
        t_request = attributes.get("t_request")
        log.info("%s %s t_request=%.3f camera=%s -> %s", event_type, event_id,
                 t_request if isinstance(t_request, (int, float)) else float("nan"), out.get("camera"),
                 f"error: {out['error']}" if "error" in out else self.describe(out))

    def _measure(self, frame: Frame, t_request: float, attributes: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The offloadable work of one frame (graph, saving the frame); its wall time feeds ``cost_ms``."""
        t0 = time.perf_counter()
        result = self.analyse(frame.image, attributes or {})
        if self.recorder is not None:
            # Saving a frame (PNG encoding, ~10 ms for 1024x768) is not part of the answer: it goes to the writer
            # thread and happens while the response travels and the robot makes its next move.
            self._save(frame)
        cost_ms = (time.perf_counter() - t0) * 1e3
        # Written from the loop or the worker, never both at once (one request at a time); a lost update under
        # concurrent use would only skew a heuristic.
        self.cost_ms = cost_ms if self.cost_ms is None else \
            self.cost_ms + self.COST_EWMA_ALPHA * (cost_ms - self.cost_ms)
        attrs = self._frame_attrs(frame, t_request)
        attrs.update(result)
        return attrs

    def analyse(self, image: Any, attributes: Mapping[str, Any]) -> dict[str, Any]:
        """The graph's answer for one frame as response attributes: ``sharpness`` or ``error``, and
        ``proc_time_ms``. A node serving another graph (:class:`aioadept.vision.locate_node.LocatorNode`) overrides
        it; ``attributes`` are the request's."""
        res = measure(image, self.graph)
        if res.ok:
            return {"proc_time_ms": res.proc_time_ms, "sharpness": float(res.sharpness)}
        return {"proc_time_ms": res.proc_time_ms, "error": res.error}

    def describe(self, out: Mapping[str, Any]) -> str:
        """The log line's summary of a successful answer."""
        return (f"sharpness={out['sharpness']:.3f} frame_t={out['frame_t']:.3f} age={out['frame_age_ms']:.1f} ms "
                f"proc={out['proc_time_ms']:.2f} ms")

    SAVE_QUEUE = 16
    """Frames waiting for the writer thread; when it falls this far behind, the node waits for it (back-pressure,
    no frame is dropped and memory stays bounded: 16 frames of 1024x768 mono8 are 12 MB)."""

    def _save(self, frame: Frame) -> None:
        """Queue ``frame`` for the recorder's writer thread (started on first use, joined by :meth:`close`)."""
        if self._save_queue is None:
            self._save_queue = queue.Queue(self.SAVE_QUEUE)
            self._save_thread = threading.Thread(target=self._save_loop, args=(self._save_queue,),
                                                 name="vision-recorder")
            self._save_thread.start()
        self._save_queue.put(frame)

    def _save_loop(self, frames: queue.Queue[Frame | None]) -> None:
        assert self.recorder is not None
        # Saving is background work: on a small machine it shares the cores with the camera, the node's loop and
        # the other nodes of the cell, whose latency counts. PNG encoding runs without the GIL, so a
        # low priority here cannot hold the loop off.
        with contextlib.suppress(OSError, AttributeError):
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), SAVE_NICE)
        while (frame := frames.get()) is not None:
            try:
                self.recorder.write(frame)
            except Exception:
                log.exception("could not save frame %s/%d", frame.camera_id, frame.seq)

    # ------------------------------------------------------------------------------------------ Responder side
    # Both handlers log with loop.call_soon: the Responder publishes the answer in the same task step right after
    # the handler returns, so the log line is written after the response has left (off the latency path).
    async def handle(self, event_type: str, event_id: str | None, attributes: Mapping[str, Any]) -> dict[str, Any]:
        """The Responder handler: never blocks the loop. A frame wait (``after``) is awaited on the loop; the graph
        runs on the loop or in the worker thread as ``graph_thread`` decides (:meth:`runs_inline`)."""
        attrs = dict(attributes)
        self._active += 1
        try:
            out = await self._serve_async(attrs)
        finally:
            self._active -= 1
        asyncio.get_running_loop().call_soon(self._log, event_type, event_id, attrs, out)
        return out

    def answers_at_once(self) -> bool:
        """Whether the next request can be answered on the loop without waiting: policy ``nearest`` (no frame
        wait), the graph on the loop (:meth:`runs_inline`) and no :meth:`handle` in progress (keeps arrival order)."""
        return (self.policy == "nearest" and not any(self.acquisition.triggered.values()) and self._active == 0
                and self.runs_inline())

    def respond(self, event_type: str, event_id: str | None,
                attributes: Mapping[str, Any]) -> dict[str, Any] | Awaitable[dict[str, Any]]:
        """A handler that answers at once when :meth:`answers_at_once` (via :meth:`handle_inline`), else returns
        the :meth:`handle` coroutine. For :class:`NodeResponder`; call from the loop."""
        if self.answers_at_once():
            return self.handle_inline(event_type, event_id, attributes)
        return self.handle(event_type, event_id, attributes)

    def handle_inline(self, event_type: str, event_id: str | None,
                      attributes: Mapping[str, Any]) -> dict[str, Any]:
        """A plain (not async) Responder handler, run by the Responder right in its socket callback: everything on
        the loop thread, blocking it during a frame wait under policy ``after`` (use it with ``nearest`` only, or
        use :meth:`handle` with ``graph_thread="never"``, which awaits the wait). Call from the loop."""
        out = self._serve(attributes, on_loop=True)
        asyncio.get_running_loop().call_soon(self._log, event_type, event_id, dict(attributes), out)
        return out

    def close(self) -> None:
        """Join the worker thread (a running graph finishes first; it takes milliseconds), then the recorder's
        writer thread once every queued frame is saved."""
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        if self._save_thread is not None:
            assert self._save_queue is not None
            self._save_queue.put(None)
            self._save_thread.join()
            self._save_thread = self._save_queue = None


class NodeResponder(Responder):
    """A :class:`Responder` serving a :class:`VisionNode` through :meth:`VisionNode.respond`: requests the node can
    answer without waiting (:meth:`VisionNode.answers_at_once`) are answered right in the socket callback; the
    others (policy ``after``, a graph sent to the worker thread) come back as awaitables that the Responder's worker
    task awaits, in arrival order. Same options as :class:`Responder`, minus the handler and ``in_thread``.

    It serves ``VisionRequest`` events only (``request_types`` by default): any other event on the request port (a
    ``Shutdown``, a ``VisionResponse`` sent back) takes no frame and no queue slot; it is ignored and counted
    (``ignored``, a debug log line each), so a stray event cannot take a request's place.
    """

    def __init__(self, request_endpoint: str, response_endpoint: str, node: VisionNode, **options: Any) -> None:
        if "in_thread" in options:
            raise TypeError("NodeResponder: the node chooses where its graph runs (graph_thread), not in_thread")
        options.setdefault("request_types", (VISION_REQUEST,))
        super().__init__(request_endpoint, response_endpoint, node.respond, **options)
        self.node = node
