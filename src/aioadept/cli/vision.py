"""``aioadept vision``: image acquisition + processing in one process (the paper's ImAcqService + ImProcNode).

Data path: sources -> one grabbing thread each -> ring buffers -> (VisionRequest over ZeroMQ) -> frame for
``t_request`` (awaited on the event loop) -> sharpness graph (on the loop when cheap, else in the node's worker
thread: ``--graph-thread``) -> VisionResponse. With the ``virtual`` source a
:class:`RobotStateFollower` subscribes to the sim's robot state stream and the virtual camera renders the
calibration object at the tool pose of each frame's time.

Endpoints are CZMQ style (``@`` binds, ``>`` connects; bare: the request SUB connects, the response PUB binds, as
in EPypes; :mod:`aioadept.bus.endpoints`). Prints one line ``READY request=<endpoint> response=<endpoint> ...`` on
stdout once it serves, each endpoint as the MCN must use it (``>addr``: connect there, ``@addr``: bind there; real
ports when bound to port 0); logs every request it serves on stderr; exits 0 on SIGINT/SIGTERM. Options may come from a TOML
file (``--config``; keys are the long option names with ``_`` or ``-``, top level or in a ``[vision]`` table);
command-line options override it. ``--figures OUTDIR`` writes the Fig. 7-9 pictures and exits.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys
import tomllib
from typing import Any

from aioadept import defaults
from aioadept.cli.options import ArgumentParser, description, option_help, with_default

log = logging.getLogger("aioadept.vision")

GRAPH_THREAD_CHOICES = ("auto", "always", "never")  # aioadept.vision.node.GRAPH_THREAD_MODES, without importing it

from aioadept.vision.options import VisionOptions  # noqa: E402  (light: neither OpenCV nor ZeroMQ)

DEFAULTS: dict[str, Any] = VisionOptions().to_dict()
DEFAULTS["source"] = ["virtual"]
"""Every option's default: one schema, :class:`aioadept.vision.options.VisionOptions`."""


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="aioadept vision", description=description(__doc__),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", metavar="FILE",
                   help="TOML file with any of these options, or a cell file (examples/cell.toml): its [vision] "
                        "table, [robot] state_endpoint, and [bus] (the transport; on zenoh the cell, the router to "
                        "connect to and the cell's keys, as the demo's application uses them); CLI overrides it")
    p.add_argument("--source", action="append", metavar="SPEC",
                   help="virtual | gige:ADDRESS (a GigE Vision camera's IPv4 address, opened by address, never by "
                        "discovery; needs the [gige] extra) | folder:PATH | opencv:SPEC (device index, video file or "
                        "URL); repeat for several cameras (default: virtual)")
    p.add_argument("--world", metavar="FILE",
                   help="the simulated world the 'world' source renders (its parts and [world.camera]): a cell file's "
                        "[world] table or the .json a starter writes; the parts follow the sim's world.state stream "
                        "on --state-endpoint")
    p.add_argument("--state-endpoint",
                   help=with_default("robot state stream to follow (virtual source; 'none': no stream, the virtual "
                                     "camera shows the target at the approach pose)",
                                     defaults.STATE_ENDPOINT))
    p.add_argument("--request-endpoint",
                   help=with_default("SUB for VisionRequest events: connects to the MCN's PUB by default, as EPypes "
                                     "nodes do; '@tcp://...' binds, '>tcp://...' connects (port 0: bind any free "
                                     "port)", defaults.REQUEST_ENDPOINT))
    p.add_argument("--response-endpoint",
                   help=with_default("PUB for VisionResponse events: binds by default; '>tcp://...' connects to a "
                                     "bound SUB (port 0: any free port)", defaults.RESPONSE_ENDPOINT))
    p.add_argument("--fps", type=float, help=option_help("grab rate cap per source", VisionOptions, "fps"))
    p.add_argument("--buffer-size", type=int, help=option_help("frames kept per source", VisionOptions, "buffer_size"))
    p.add_argument("--focus-offset-mm", type=float,
                   help=option_help("virtual camera: focal plane this far along tool +z from the approach pose",
                                    VisionOptions, "focus_offset_mm"))
    p.add_argument("--working-distance-mm", type=float,
                   help=option_help("virtual camera: lens to target at the approach pose", VisionOptions,
                                    "working_distance_mm"))
    p.add_argument("--f-number", type=float,
                   help=option_help("virtual camera: lens f-number", VisionOptions, "f_number"))
    p.add_argument("--noise-sigma", type=float,
                   help=option_help("virtual camera: sensor noise, grey levels", VisionOptions, "noise_sigma"))
    p.add_argument("--seed", type=int, help="virtual camera: noise seed")
    p.add_argument("--policy", choices=("nearest", "after"),
                   help="free-running sources: the frame for a request: the first exposed at/after t_request "
                        "(default: never a frame from before the request), or nearest in time (the paper; opt-in, "
                        "bounded by --max-frame-age)")
    p.add_argument("--max-frame-age", type=float, metavar="S",
                   help="policy nearest: answer with an error rather than from a frame exposed more than S seconds "
                        "before the request (default 0.1; inf: no check)")
    p.add_argument("--trigger", choices=("auto", "software", "free"),
                   help="acquisition: auto (default: each request software-triggers its own exposure on sources "
                        "that can, the virtual camera; others run free), software (insist), free (free-running at "
                        "--fps)")
    p.add_argument("--exposure-ms", type=float,
                   help="exposure time, ms: the virtual camera's, and written to GigE cameras (default 5)")
    p.add_argument("--pixel-format", help="GigE cameras: PixelFormat written at open: Mono8 (default), Mono16, "
                                          "BayerRG8/GR8/GB8/BG8 (converted to mono8)")
    p.add_argument("--readout-ms", type=float,
                   help="virtual camera: readout + transfer time, ms (default: frame bytes over 1 Gbit/s GigE, 6.3 "
                        "ms for 1024x768 mono8)")
    p.add_argument("--frame-timeout", type=float,
                   help=option_help("max wait for a frame", VisionOptions, "frame_timeout"))
    p.add_argument("--graph", choices=("sharpness", "frame-sharpness", "noop", "locate"),
                   help="processing graph: sharpness (the paper's, of the calibration object; default), "
                        "frame-sharpness (the whole frame, no object search: aiming a real camera), noop (latency "
                        "tests), locate (the part locator: answers LocateRequest events; needs --calibration)")
    p.add_argument("--calibration", metavar="FILE",
                   help="--graph locate: the cell file whose [calibration] table holds the camera's intrinsics and "
                        "pose in the robot base frame (aioadept calibrate writes it)")
    p.add_argument("--part-height-mm", type=float,
                   help="--graph locate: height of the parts' top faces above the table (default: unknown; marked "
                        "parts then use the marker's own depth, coloured parts need it in the request)")
    p.add_argument("--marker-mm", type=float, help="--graph locate: side of the parts' ArUco markers (default 15)")
    p.add_argument("--aruco-dict", help="--graph locate: the markers' ArUco dictionary (default DICT_4X4_50)")
    p.add_argument("--graph-thread", choices=GRAPH_THREAD_CHOICES,
                   help="where the graph runs: auto (default: on the event loop while its measured cost is at most "
                        "--graph-inline-max-ms, else in the node's worker thread), always (worker), never (loop)")
    p.add_argument("--graph-inline-max-ms", type=float,
                   help="--graph-thread auto: moving average of a run's cost, ms, up to which it runs on the loop "
                        "(default 5)")
    p.add_argument("--inline", action="store_true", default=None,
                   help="same as --graph-thread never (kept for old command lines)")
    p.add_argument("--max-state-age", type=float, metavar="S",
                   help="virtual camera: answer with an error instead of a sharpness when the newest robot state "
                        "is more than S seconds older than the frame (the state stream went silent; default 0.5; "
                        "inf: no check)")
    p.add_argument("--max-queue", type=int, metavar="N",
                   help="requests kept waiting; when full the oldest waiting one is dropped and answered with a "
                        "'dropped:' error (default 32)")
    p.add_argument("--max-request-bytes", type=int, metavar="N",
                   help="larger request frames are discarded unparsed and their sender disconnected "
                        "(ZMQ_MAXMSGSIZE; default 1048576)")
    p.add_argument("--save-frames", metavar="DIR", help="save every served frame (PNG + frames.csv) into DIR")
    p.add_argument("--figures", metavar="OUTDIR", help="write the graph / intermediate results / sweep pictures "
                                                         "(Figs. 7-9) into OUTDIR and exit")
    p.add_argument("--log-level", help="DEBUG, INFO (default), WARNING")
    p.add_argument("--state-curve-secret", metavar="FILE",
                   help="CURVE for the robot state stream: this node's secret certificate (NAME.key_secret)")
    p.add_argument("--state-curve-server", metavar="FILE",
                   help="CURVE for the robot state stream: the sim's public certificate (NAME.key)")
    p.add_argument("--curve-secret", metavar="FILE",
                   help="CURVE: this node's secret certificate (NAME.key_secret, aioadept.bus.security.save_keypair); "
                        "turns on CURVE authentication and encryption of requests and responses (docs/security.md)")
    p.add_argument("--curve-allow", action="append", metavar="FILE",
                   help="CURVE: public certificate (NAME.key) of a requester allowed in (repeatable; without any, "
                        "every requester that knows the node's public key is accepted)")
    from aioadept.cli.options import add_insecure_option, add_node_transport_options

    add_node_transport_options(p)
    add_insecure_option(p)
    return p


def load_config(path: str) -> dict[str, Any]:
    """Options from a TOML file, checked against the one vision schema (:class:`VisionOptions`); raises
    :class:`aioadept.errors.ConfigError` naming the file and the key.

    A file with a ``[vision]`` (or ``[robot]``, ``[focus]``, ``[run]``, ``[bus]``) table is read as a cell file
    (``examples/cell.toml``: the whole file is checked as ``demo`` checks it; the node takes ``[vision]``, and the
    robot's ``state_endpoint`` unless ``[vision]`` has its own; a starter's ``start`` is ignored and ``vision_args``
    come before the command line's; :func:`resolve_options` applies its ``[bus]``). Otherwise the options are the
    top-level keys, with ``_`` or ``-``.
    """
    return _load_config(path)[0]


def _load_config(path: str) -> tuple[dict[str, Any], Any]:
    """:func:`load_config`'s options, and the cell file's ``[bus]`` table (a
    :class:`~aioadept.cell.bus.BusSection`; None for a file of options only)."""
    from aioadept.cell.schema import load_toml

    data = load_toml(path)  # the file named, and the line of bad TOML (the reader every --config shares)
    bus = None
    if set(data) & {"robot", "vision", "focus", "run", "bus"}:  # a cell file: one schema, checked as demo checks it
        from aioadept.cell.config import CellConfig

        cfg = CellConfig.from_dict(data, source=str(path))
        table = {str(k).replace("-", "_") for k in (data.get("vision") or {})}
        out = {k: v for k, v in cfg.vision.to_dict().items() if k in table}
        if "state_endpoint" not in out and "state_endpoint" in (data.get("robot") or {}):
            out["state_endpoint"] = cfg.robot.state_endpoint
        if "world" not in out and cfg.world is not None:
            out["world"] = str(path)  # the cell file's own [world]
        if cfg.vision.vision_args:
            out["vision_args"] = list(cfg.vision.vision_args)
        if cfg.calibration is not None and "calibration" not in out:  # the locator's camera: this cell's own
            out["calibration"] = str(path)
        bus = cfg.bus
    else:
        opts = VisionOptions.from_table(data, str(path))
        out = {k: v for k, v in opts.to_dict().items() if k in {str(k).replace("-", "_") for k in data}}
    if isinstance(out.get("source"), str):
        out["source"] = [out["source"]]
    return out, bus


def resolve_options(argv: list[str]) -> argparse.Namespace:
    """Defaults < config file < command line."""
    parser = build_parser()
    merged, given, bus, config = _merged(parser, argv)
    streams = {"request_endpoint": (defaults.REQUEST_ENDPOINT, "vision", "request"),
               "response_endpoint": (defaults.RESPONSE_ENDPOINT, "vision", "response"),
               "state_endpoint": (defaults.STATE_ENDPOINT, "sim", "state")}
    if bus is not None:  # the cell file's [bus]: the transport and keys of the demo's application
        from aioadept.cli.options import apply_cell_bus

        try:
            apply_cell_bus(merged, bus, given, {k: v[1:] for k, v in streams.items()}, config)
        except ValueError as exc:
            from aioadept.cell.schema import report

            raise SystemExit(report("aioadept vision", exc)) from None
    _check_values(parser, merged)
    _check_endpoints(parser, merged, streams)
    merged["curve"] = _curve_server(parser, merged)
    from aioadept.cli.options import check_listeners, zenoh_listener, zmq_listener

    curve = merged["curve"] is not None
    try:
        check_listeners("aioadept vision", [
            *zmq_listener("--request-endpoint", merged["request_endpoint"], False, curve,
                          "send the node requests"),
            *zmq_listener("--response-endpoint", merged["response_endpoint"], True, curve, "read its answers"),
            *zmq_listener("--state-endpoint", merged["state_endpoint"], False, False,
                          "forge the robot state it measures against"),
            *zenoh_listener(merged, "read and publish the cell's streams")], bool(merged.get("insecure")))
    except ValueError as exc:
        parser.error(str(exc))
    _load_files(parser, merged)
    return argparse.Namespace(**merged)


def _merged(parser: argparse.ArgumentParser, argv: list[str]) -> tuple[dict[str, Any], set[str], Any, Any]:
    """The defaults, the cell file's options and the command line's, in that order; the keys the command line
    gave, the cell file's [bus] table (or None) and the cell file's path."""
    args = parser.parse_args(argv)
    merged = dict(DEFAULTS)
    merged.update(transport="zeromq", cell=None, zenoh_connect=None, zenoh_listen=None, zenoh_config=None, node=None)
    bus = None
    if args.config:
        try:
            options, bus = _load_config(args.config)
            merged.update(options)
        except (OSError, ValueError, tomllib.TOMLDecodeError) as exc:  # one line naming the file and the key
            from aioadept.cell.schema import report

            raise SystemExit(report("aioadept vision", exc)) from None
        extra = merged.pop("vision_args", None)
        if extra:  # the cell file's further arguments, overridden by the command line's
            args = parser.parse_args([*extra, *argv])
    given = set()
    for key, value in vars(args).items():
        if key != "config" and value is not None:
            merged[key] = value
            given.add(key)
    return merged, given, bus, args.config


def _check_values(parser: argparse.ArgumentParser, merged: dict[str, Any]) -> None:
    """The option values' own checks (an error names the option); the two ages become floats."""
    if merged["policy"] not in ("nearest", "after"):
        parser.error(f"policy must be nearest or after, got {merged['policy']!r}")
    if merged["inline"]:
        if merged["graph_thread"] not in ("auto", "never"):
            parser.error("--inline means --graph-thread never; do not give both")
        merged["graph_thread"] = "never"
    if merged["graph_thread"] not in GRAPH_THREAD_CHOICES:
        parser.error(f"graph-thread must be one of {', '.join(GRAPH_THREAD_CHOICES)}, got {merged['graph_thread']!r}")
    if float(merged["graph_inline_max_ms"]) < 0:
        parser.error("graph-inline-max-ms must be >= 0")
    for key in ("max_state_age", "max_frame_age"):
        try:
            age = float(merged[key])
        except (TypeError, ValueError):
            age = float("nan")
        if not age > 0:  # NaN too
            parser.error(f"{key.replace('_', '-')} must be > 0 seconds (inf: no check), got {merged[key]!r}")
        merged[key] = age
    if merged["trigger"] not in ("auto", "software", "free"):
        parser.error(f"trigger must be auto, software or free, got {merged['trigger']!r}")
    for key in ("exposure_ms", "readout_ms"):
        value = merged[key]
        if value is None and key == "readout_ms":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < float("inf"):
            parser.error(f"{key.replace('_', '-')} must be a finite number >= 0, got {value!r}")
    for key in ("max_queue", "max_request_bytes"):
        value = merged[key]
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            parser.error(f"{key.replace('_', '-')} must be an integer >= 1, got {value!r}")


def _check_endpoints(parser: argparse.ArgumentParser, merged: dict[str, Any], streams: dict[str, tuple]) -> None:
    """The transport's endpoints or keys, each parsed, and the ranges VisionOptions holds its fields to."""
    from aioadept.cli.options import apply_node_transport

    try:
        apply_node_transport(merged, "vision", streams)
    except ValueError as exc:
        parser.error(str(exc))
    from aioadept.bus.endpoints import is_none, parse_endpoint
    from aioadept.errors import BusError

    for key in ("request_endpoint", "response_endpoint", "state_endpoint"):
        if key == "state_endpoint" and is_none(merged[key]):
            continue
        try:
            parse_endpoint(merged[key])
        except BusError as exc:
            parser.error(f"--{key.replace('_', '-')}: {exc}")
    from aioadept.cell.schema import check_ranges

    try:  # the ranges of VisionOptions' fields, the same the cell file is checked against
        check_ranges(VisionOptions(**{k: merged[k] for k in VisionOptions.__dataclass_fields__}))
    except ValueError as exc:
        parser.error(str(exc))


def _load_files(parser: argparse.ArgumentParser, merged: dict[str, Any]) -> None:
    """The world of ``--source world`` and the calibration of ``--graph locate``, loaded before anything starts."""
    merged["world_config"] = None
    if "world" in merged["source"]:
        if not merged["world"]:
            parser.error("--source world needs --world FILE (a cell file with [world], or its .json)")
        from aioadept.cell.schema import report
        from aioadept.cell.world import load_world

        try:
            merged["world_config"] = load_world(merged["world"])
        except (OSError, ValueError) as exc:
            raise SystemExit(report("aioadept vision", exc)) from None
        if merged["world_config"].camera is None:
            raise SystemExit(report("aioadept vision", ValueError(
                f"{merged['world']}: the world has no [world.camera] for --source world")))
    merged["locate_calibration"] = None
    if merged["graph"] == "locate":
        if not merged["calibration"]:
            parser.error("--graph locate needs --calibration FILE (a cell file with a [calibration] table)")
        from aioadept.cell.schema import report
        from aioadept.vision.calibration import load_calibration

        try:  # before anything starts: one line naming the file and the key
            merged["locate_calibration"] = load_calibration(merged["calibration"])
        except ValueError as exc:
            raise SystemExit(report("aioadept vision", exc)) from None


def _curve_server(parser: argparse.ArgumentParser, merged: dict[str, Any]) -> Any:
    """The CurveServer of --curve-secret/--curve-allow, or None (CURVE off, the default)."""
    allow = merged["curve_allow"]
    if isinstance(allow, str):
        allow = [allow]
    if not merged["curve_secret"]:
        if allow:
            parser.error("--curve-allow needs --curve-secret")
        return None
    from aioadept.bus.security import CurveServer, load_keypair

    try:
        keys = load_keypair(merged["curve_secret"])
        if keys.secret is None:
            raise ValueError(f"{merged['curve_secret']} holds no secret key (give the .key_secret file)")
        return CurveServer(keys, allowed_clients=[load_keypair(f).public for f in allow] if allow else None)
    except ValueError as exc:
        parser.error(str(exc))


def main(argv: list[str] | None = None) -> int:
    opts = resolve_options(list(sys.argv[1:] if argv is None else argv))
    from aioadept.cli.options import setup_logging

    setup_logging(getattr(logging, str(opts.log_level).upper(), logging.INFO),
                  fmt="%(asctime)s %(levelname)s %(name)s: %(message)s")
    if opts.figures:
        from aioadept.vision.figures import write_figures

        for path in write_figures(opts.figures, focus_offset_mm=opts.focus_offset_mm):
            print(path)
        return 0
    from aioadept.errors import AdeptError, BusError
    from aioadept.vision.service import serve

    try:
        return asyncio.run(serve(opts))
    except (ValueError, OSError, AdeptError) as exc:
        # One line, as every node's failure, without the log's timestamp and level. A bus it cannot open or reach
        # (a Zenoh router that does not answer or refuses it, an address in use) exits 1 as sim and state do; the
        # rest 2, a usage error: the node cannot tell a source it was given wrong from one that does not answer (both
        # are VisionError).
        print(f"aioadept vision: {exc}", file=sys.stderr)
        return 1 if isinstance(exc, BusError) else 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
