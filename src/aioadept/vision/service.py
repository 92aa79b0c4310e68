"""The vision node as a service: build the cameras of ``--source`` specs, serve requests until SIGINT/SIGTERM
(:func:`serve`); ``aioadept vision`` (:mod:`aioadept.cli.vision`) parses the options and calls it.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
from pathlib import Path
from typing import Any

log = logging.getLogger("aioadept.vision")

# The READY line's ``thread=`` field: where graphs run.
THREAD_WORDS = {"auto": "auto", "always": "worker", "never": "loop"}


def _state_curve(opts: argparse.Namespace) -> Any:
    """The CurveClient for the robot state stream, or None (plain, the default)."""
    secret, server = getattr(opts, "state_curve_secret", None), getattr(opts, "state_curve_server", None)
    if not secret and not server:
        return None
    if not (secret and server):
        raise SystemExit("aioadept vision: --state-curve-secret and --state-curve-server go together")
    from aioadept.bus.security import CurveClient, load_keypair

    return CurveClient(load_keypair(secret), load_keypair(server).public)


def make_sources(opts: argparse.Namespace, pose_at: Any, state_age: Any = None, pose_guess: Any = None, *,
                 world_parts: Any = None, world_age: Any = None) -> list[Any]:
    """Camera objects for the ``--source`` specs (unique camera ids). ``pose_at`` / ``state_age`` / ``pose_guess``:
    the robot state follower's (``pose_if_at_rest``), for virtual cameras (and ``pose_at`` for the world camera's
    tool marker); ``world_parts``: the world state follower's ``parts`` (None: the parts where the cell file puts
    them) and ``state_age_s``, for the world camera."""
    from aioadept.vision.sources import ImageFolderSource, OpenCVSource
    from aioadept.vision.virtual_camera import LensOptics, paper_camera

    sources: list[Any] = []
    seen: set[str] = set()

    def unique(cid: str) -> str:
        base, n = cid, 1
        while cid in seen:
            cid, n = f"{base}{n}", n + 1
        seen.add(cid)
        return cid

    for spec in opts.source:
        kind, _, arg = spec.partition(":")
        if kind == "virtual":
            sources.append(paper_camera(pose_at, focus_offset_mm=opts.focus_offset_mm,
                                        working_distance_mm=opts.working_distance_mm,
                                        optics=LensOptics(f_number=opts.f_number), noise_sigma=opts.noise_sigma,
                                        seed=opts.seed, camera_id=unique("virtual"), state_age=state_age,
                                        exposure_ms=opts.exposure_ms, readout_ms=opts.readout_ms,
                                        pose_guess=pose_guess))
        elif kind == "world":
            from aioadept.vision.world_camera import WorldCameraSource, WorldView

            parts = world_parts if world_parts is not None else (lambda: None)
            sources.append(WorldCameraSource(WorldView(opts.world_config, seed=opts.seed), parts,
                                             state_age=world_age, tool_at=pose_at, camera_id=unique("world"),
                                             exposure_ms=opts.exposure_ms,
                                             readout_ms=opts.readout_ms))
        elif kind == "folder" and arg:
            csv_path = Path(arg) / "frames.csv"
            # A recorded folder (--save-frames) replays with its times; any other folder loops, stamped live.
            sources.append(ImageFolderSource(arg, camera_id=unique("folder"),
                                             timestamps_csv=csv_path if csv_path.exists() else None,
                                             loop=not csv_path.exists()))
        elif kind == "gige" and arg:
            from aioadept.vision.gige import GigECamera

            sources.append(GigECamera(arg, camera_id=unique(f"gige:{arg}"), exposure_ms=opts.exposure_ms or None,
                                      pixel_format=opts.pixel_format, timeout_s=float(opts.frame_timeout)))
        elif kind == "opencv" and arg:
            sources.append(OpenCVSource(arg, camera_id=unique(f"opencv:{arg}")))
        else:
            raise ValueError(f"bad --source {spec!r}: use virtual, world, gige:ADDRESS, folder:PATH or opencv:SPEC")
    return sources


def locate_hyperparameters(opts: argparse.Namespace) -> dict[str, Any]:
    """The locator graph's frozen tokens from the options (``--part-height-mm``, ``--marker-mm``, ``--aruco-dict``)."""
    return {"height_mm": opts.part_height_mm, "marker_mm": float(opts.marker_mm), "dictionary": opts.aruco_dict}


async def serve(opts: argparse.Namespace) -> int:
    from aioadept.vision.acquisition import Acquisition
    from aioadept.vision.node import NodeResponder, VisionNode, noop_graph
    from aioadept.vision.sharpness import frame_sharpness_graph, sharpness_graph
    from aioadept.vision.sources import FrameRecorder
    from aioadept.vision.virtual_camera import RobotStateFollower

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)

    follower = None
    from aioadept.bus.endpoints import is_none

    # the robot's tool pose: for a virtual camera, and for the world camera's tool marker
    tool_marker = "world" in opts.source and getattr(opts.world_config, "tool_marker", None) is not None
    if (tool_marker or any(s.split(":", 1)[0] == "virtual" for s in opts.source)) \
            and not is_none(opts.state_endpoint):
        follower = RobotStateFollower(opts.state_endpoint, curve=_state_curve(opts)).start()
    world_follower = None
    if "world" in opts.source and not is_none(opts.state_endpoint):
        from aioadept.vision.world_camera import WorldStateFollower

        world_follower = WorldStateFollower(opts.state_endpoint, curve=_state_curve(opts)).start()
    recorder = FrameRecorder(opts.save_frames) if opts.save_frames else None
    acq = node = responder = None
    try:
        sources = make_sources(opts, follower.pose_at if follower else None,
                               follower.state_age_s if follower else None,
                               follower.pose_if_at_rest if follower else None,
                               world_parts=world_follower.parts if world_follower else None,
                               world_age=world_follower.state_age_s if world_follower else None)
        acq = Acquisition(sources, buffer_size=opts.buffer_size, fps=opts.fps, trigger=opts.trigger).start()
        # Serve only once every camera has a frame: the first render/read pays one-off costs (imports, caches).
        if not await asyncio.to_thread(acq.wait_ready, 10.0):
            log.warning("not every camera delivered a frame within 10 s; serving anyway")
        node_options = dict(policy=opts.policy, timeout_s=opts.frame_timeout, recorder=recorder,
                            graph_thread=opts.graph_thread, inline_max_ms=float(opts.graph_inline_max_ms),
                            max_state_age_s=opts.max_state_age, max_frame_age_s=opts.max_frame_age)
        responder_options = dict(max_queue=opts.max_queue, max_request_bytes=opts.max_request_bytes,
                                 **({"curve": opts.curve} if opts.curve is not None else {}))
        if opts.graph == "locate":  # the part locator: LocateRequest events, answered with parts in base coordinates
            from aioadept.vision.locate_node import LocatorNode, locate_responder

            node = LocatorNode(acq, opts.locate_calibration, hyperparameters=locate_hyperparameters(opts),
                               **node_options)
            responder = locate_responder(opts.request_endpoint, opts.response_endpoint, node, **responder_options)
        else:
            graph = (noop_graph() if opts.graph == "noop" else
                     frame_sharpness_graph() if opts.graph == "frame-sharpness" else sharpness_graph())
            node = VisionNode(acq, graph, **node_options)
            # Frame waits are awaited on the loop and the graph runs where --graph-thread says, so the loop is
            # never blocked for longer than one cheap graph run; requests that need no waiting are answered in the
            # socket callback (NodeResponder).
            responder = NodeResponder(opts.request_endpoint, opts.response_endpoint, node, **responder_options)
        responder.start()
        cams = ",".join(acq.camera_ids)
        from aioadept.bus.endpoints import opposite

        # request=/response=: the form the MCN uses (e.g. request=@tcp://127.0.0.1:5555: bind your PUB there;
        # response=>tcp://...: connect your SUB there), so the line can be passed on as is (aioadept focus
        # --request-endpoint/--response-endpoint). node_request=/node_response=: the same links as this node uses
        # them (real ports), so neither side has to be guessed.
        mcn_req, mcn_resp = responder.peer_request_endpoint, responder.peer_response_endpoint
        from aioadept.bus.zenoh import announce_ready

        announce_ready()  # --transport zenoh: the node's liveliness token, as it starts serving (no-op on ZeroMQ)
        print(f"READY request={mcn_req} response={mcn_resp} node_request={opposite(mcn_req)} "
              f"node_response={opposite(mcn_resp)} "
              f"cameras={cams} fps={opts.fps:g} policy={opts.policy} graph={opts.graph} "
              f"trigger={'software' if any(acq.triggered.values()) else 'free'} "
              f"thread={THREAD_WORDS[opts.graph_thread]} "
              f"state={opts.state_endpoint if follower else 'none'}", flush=True)
        log.info("serving %s requests on %s (the MCN's PUB: %s), responses on %s (the MCN's SUB: %s); cameras %s at "
                 "%g fps, policy %s, graph thread %s%s", opts.graph, opposite(mcn_req), mcn_req, opposite(mcn_resp),
                 mcn_resp, cams, opts.fps, opts.policy, opts.graph_thread,
                 f", following robot state on {opts.state_endpoint}" if follower else ", no robot state stream")
        stop_task = asyncio.create_task(stop.wait())
        serve_task = asyncio.create_task(responder.wait_closed())
        done, _ = await asyncio.wait({stop_task, serve_task}, return_when=asyncio.FIRST_COMPLETED)
        stop_task.cancel()
        if serve_task in done and serve_task.exception() is not None:
            log.error("responder failed: %r", serve_task.exception())
            return 1
        serve_task.cancel()
        log.info("stopping: %d requests served (%d failed, %d of them for a stale robot state), %d dropped (queue "
                 "full), %d refused (bad t_deadline), %d ignored (other event types); graph runs on the loop %d, "
                 "in the worker %d", node.served, node.failed, node.stale, responder.dropped, responder.rejected,
                 responder.ignored, node.inline_runs, node.thread_runs)
        return 0
    finally:
        if responder is not None:
            await responder.aclose()
        if node is not None:
            node.close()
        if acq is not None:
            acq.stop()
        if follower is not None:
            follower.stop()
        if world_follower is not None:
            world_follower.stop()
        if recorder is not None:
            recorder.close()
