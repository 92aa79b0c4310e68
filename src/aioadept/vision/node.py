"""The processing node (the paper's ImProcNode): a vision request in, the frame(s) for its time through the graph,
a response out.

Where it sits: :class:`aioadept.bus.communicator.Responder` receives ``VisionRequest`` events and calls
:meth:`VisionNode.handle`; the node picks the frame for ``t_request`` from the :class:`Acquisition` ring buffers
(policy ``nearest`` or ``after``), runs the computational graph in its own worker thread (so the event loop keeps
receiving, and repeated request ids are answered from the Responder's cache meanwhile), and returns the response
attributes of docs/interfaces.md:

- ``sharpness`` (DOUBLE), ``frame_t`` (DOUBLE, epoch s of the frame), ``proc_time_ms`` (DOUBLE, the graph run);
- ``error`` (STRING) instead of ``sharpness`` when it failed: no frame for that time, no object found;
- also ``camera`` (STRING), ``frame_seq`` (INT) and ``frame_age_ms`` (DOUBLE, ``t_request - frame_t``).

A request with attribute ``camera`` is answered from that camera; without it from the first camera, and when the
node has several cameras the others' results are added as ``sharpness.<camera>`` / ``frame_t.<camera>`` /
``error.<camera>`` (one frame set per request, as FxIS grabs several cameras together).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from aioadept.errors import VisionError
from aioadept.vision.acquisition import Acquisition, Policy
from aioadept.vision.graph import CompGraph
from aioadept.vision.sharpness import measure, sharpness_graph
from aioadept.vision.sources import Frame, FrameRecorder

log = logging.getLogger(__name__)


def noop_graph() -> CompGraph:
    """A one-function graph answering ``sharpness = 0.0`` without looking at the image: for latency benchmarks."""
    return CompGraph({"noop": lambda image: 0.0}, {"noop": ("image", "sharpness")}, name="noop")


class VisionNode:
    """Turns a request's attributes into response attributes; see the module docstring.

    ``graph`` has free token ``image`` and output ``sharpness`` (default: :func:`sharpness_graph`). ``timeout_s``
    bounds the wait for a frame under policy ``after``. ``recorder`` saves every frame the node serves. Owns one
    worker thread (created on first use, joined by :meth:`close`).
    """

    def __init__(self, acquisition: Acquisition, graph: CompGraph | None = None, *, policy: Policy = "nearest",
                 timeout_s: float = 1.0, recorder: FrameRecorder | None = None) -> None:
        self.acquisition = acquisition
        self.graph = graph if graph is not None else sharpness_graph()
        self.policy = policy
        self.timeout_s = timeout_s
        self.recorder = recorder
        self.served = 0
        self.failed = 0
        self._executor: ThreadPoolExecutor | None = None

    # ------------------------------------------------------------------------------------------ sync core
    def process(self, event_type: str, event_id: str | None, attributes: Mapping[str, Any]) -> dict[str, Any]:
        """Answer one request (blocking: may wait for a frame and runs the graph), and log it."""
        out = self._serve(attributes)
        self._log(event_type, event_id, attributes, out)
        return out

    def _serve(self, attributes: Mapping[str, Any]) -> dict[str, Any]:
        t_request = float(attributes.get("t_request", time.time()))
        camera = attributes.get("camera")
        cameras = [str(camera)] if camera else list(self.acquisition.camera_ids)
        out: dict[str, Any] = {}
        deadline = time.monotonic() + self.timeout_s
        for i, cid in enumerate(cameras):
            try:
                frame = self.acquisition.frame_at(t_request, camera_id=cid, policy=self.policy,
                                                  timeout_s=max(0.0, deadline - time.monotonic()))
            except VisionError as exc:
                result = {"error": str(exc), "camera": cid}
            else:
                result = self._measure(frame, t_request)
            if i == 0:
                out.update(result)
            else:
                for key in ("sharpness", "frame_t", "error"):
                    if key in result:
                        out[f"{key}.{cid}"] = result[key]
        if "error" in out:
            self.failed += 1
        self.served += 1
        return out

    def _log(self, event_type: str, event_id: str | None, attributes: Mapping[str, Any],
             out: Mapping[str, Any]) -> None:
        if not log.isEnabledFor(logging.INFO):
            return
        log.info("%s %s t_request=%.3f camera=%s -> %s", event_type, event_id,
                 float(attributes.get("t_request", float("nan"))), out.get("camera"),
                 (f"error: {out['error']}" if "error" in out else
                  f"sharpness={out['sharpness']:.3f} frame_t={out['frame_t']:.3f} "
                  f"age={out['frame_age_ms']:.1f} ms proc={out['proc_time_ms']:.2f} ms"))

    def _measure(self, frame: Frame, t_request: float) -> dict[str, Any]:
        res = measure(frame.image, self.graph)
        if self.recorder is not None:
            try:
                self.recorder.write(frame)
            except Exception:
                log.exception("could not save frame %s/%d", frame.camera_id, frame.seq)
        attrs: dict[str, Any] = {
            "frame_t": frame.t_s, "proc_time_ms": res.proc_time_ms, "camera": frame.camera_id,
            "frame_seq": int(frame.seq), "frame_age_ms": (t_request - frame.t_s) * 1e3,
        }
        if res.ok:
            attrs["sharpness"] = float(res.sharpness)
        else:
            attrs["error"] = res.error
        return attrs

    # ------------------------------------------------------------------------------------------ Responder side
    # Both handlers log with loop.call_soon: the Responder publishes the answer in the same task step right after
    # the handler returns, so the log line is written after the response has left (off the latency path).
    async def handle(self, event_type: str, event_id: str | None, attributes: Mapping[str, Any]) -> dict[str, Any]:
        """The Responder handler: frame lookup and graph in the node's worker thread."""
        if self._executor is None:
            self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vision-node")
        loop = asyncio.get_running_loop()
        attrs = dict(attributes)
        out = await loop.run_in_executor(self._executor, self._serve, attrs)
        loop.call_soon(self._log, event_type, event_id, attrs, out)
        return out

    def handle_inline(self, event_type: str, event_id: str | None,
                      attributes: Mapping[str, Any]) -> dict[str, Any]:
        """The Responder handler that runs on the event loop thread (one thread hand-off less per request; the
        Responder serves one request at a time either way). Call from the loop."""
        out = self._serve(attributes)
        asyncio.get_running_loop().call_soon(self._log, event_type, event_id, dict(attributes), out)
        return out

    def close(self) -> None:
        """Join the worker thread (a running graph finishes first; it takes milliseconds)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
