"""``aioadept ros2``: the robot state as ROS 2 sees it: every robot.state sample put again as a
``sensor_msgs/msg/JointState`` on the key expression ROS 2's Zenoh middleware (rmw_zenoh, Jazzy and later) uses.

Follows ``--state-endpoint`` (the sim's or ``aioadept state``'s ZeroMQ stream, or a ``zenoh:KEY`` stream) and puts
each sample on ``<domain>/<topic>/sensor_msgs::msg::dds_::JointState_/RIHS01_...`` with rmw_zenoh's attachment, so
``ros2 topic echo /joint_states`` on rmw_zenoh_cpp, connected to the same Zenoh router, prints the arm (the URDF's
names of ``--robot-model``'s joints: joint_1..joint_6 on a Viper, joint_1..joint_4 on a Cobra; radians, metres for
a Cobra's quill). It is node ``--node-name`` in ``--namespace`` of the ROS 2 graph, with one publisher
(rmw_zenoh's liveliness tokens, held while it runs), so ``ros2 node list`` and ``ros2 topic list`` show it.
Multicast scouting is off: it is the router (``--zenoh-listen``) or connects to one (``--zenoh-connect``). Prints
``READY ros2=KEY state=ENDPOINT node=/NAMESPACE/NAME`` once it follows; runs until SIGINT/SIGTERM. What was checked
and what was not: docs/bus.md, "ROS 2".
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import sys

from aioadept import defaults
from aioadept.robots import DEFAULT_MODEL, MODELS
from aioadept.cli.options import (ArgumentParser, DefaultsHelpFormatter, add_insecure_option,
                                  add_zenoh_session_options, check_listeners, description, zenoh_listener,
                                  zenoh_session_options)


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="aioadept ros2", description=description(__doc__), formatter_class=DefaultsHelpFormatter)
    p.add_argument("--state-endpoint", default=defaults.STATE_ENDPOINT, dest="state_endpoint",
                   help="the robot.state stream to follow: a ZeroMQ endpoint (as aioadept sim --state-endpoint) or "
                        "zenoh:KEY (a sim with --transport zenoh: zenoh:aioadept/CELL/sim/state)")
    p.add_argument("--topic", default="joint_states",
                   help="the ROS 2 topic, expanded as a node's: joint_states is /NAMESPACE/joint_states, "
                        "/joint_states stays, ~/joint_states is /NAMESPACE/NODE/joint_states")
    p.add_argument("--domain", type=int, default=0, help="the ROS 2 domain id (ROS_DOMAIN_ID), 0..232")
    p.add_argument("--frame-id", default="", dest="frame_id", help="the JointState's header.frame_id")
    p.add_argument("--robot-model", default=DEFAULT_MODEL, choices=sorted(MODELS), dest="robot_model",
                   metavar="NAME", help="the arm the stream is of (as aioadept sim --robot-model): its joint names "
                                        "and units; a sample with another number of joints is skipped")
    p.add_argument("--node-name", default="aioadept_ros2", dest="node_name",
                   help="the ROS 2 node this relay is in the graph (ros2 node list)")
    p.add_argument("--namespace", default="/", help="the node's namespace, e.g. /cell1 (a relative --topic goes "
                                                    "into it)")
    add_zenoh_session_options(p, router=", e.g. rmw_zenohd's")
    add_insecure_option(p)
    p.add_argument("--no-lowlatency", action="store_false", dest="lowlatency",
                   help="Zenoh's default unicast transport instead of the low-latency one aioadept's nodes use: "
                        "needed with a router that is not low-latency, e.g. ROS 2's rmw_zenohd as installed")
    p.add_argument("--log-level", default="WARNING", dest="log_level", help="logging level on stderr")
    return p


def _options(args: argparse.Namespace):  # -> (topic key, ZenohOptions)
    from aioadept.bus import ros2
    from aioadept.bus import zenoh as zb
    from aioadept.errors import BusError

    opts = zenoh_session_options(args.zenoh_listen, args.zenoh_connect, args.zenoh_config,
                                 lowlatency=args.lowlatency)
    check_listeners("aioadept ros2", zenoh_listener(args, "read and publish the cell's streams"), args.insecure)
    try:
        ros2.check_node_name(args.node_name)
        ros2.check_namespace(args.namespace)
        topic = ros2.expand_topic_name(args.topic, node_name=args.node_name, namespace=args.namespace)
        key = ros2.topic_key(topic, domain_id=args.domain)
    except BusError as exc:
        raise ValueError(str(exc)) from None
    try:  # a bad one is one line, exit 2, before any session opens
        if zb.is_zenoh(args.state_endpoint):
            zb.key_of(args.state_endpoint)
        else:
            from aioadept.bus.endpoints import parse_endpoint

            parse_endpoint(args.state_endpoint)
    except BusError as exc:
        raise ValueError(f"--state-endpoint: {exc}") from None
    return key, opts


async def run(args: argparse.Namespace, opts) -> int:
    from aioadept.bus import zenoh as zb
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber
    from aioadept.bus.ros2 import JointStatePublisher
    from aioadept.robots import model as robot_model
    from aioadept.errors import BusError

    log = logging.getLogger("aioadept.ros2")
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    zb.configure(opts)
    pub = JointStatePublisher(args.topic, domain_id=args.domain, frame_id=args.frame_id, node_name=args.node_name,
                              namespace=args.namespace, arm=robot_model(args.robot_model))
    bad = 0
    try:
        async with Subscriber(args.state_endpoint, topics=(ROBOT_STATE_TOPIC,)) as sub:
            node = args.namespace.rstrip("/") + "/" + args.node_name
            print(f"READY ros2={pub.key} state={args.state_endpoint} node={node}", flush=True)

            async def follow() -> None:
                nonlocal bad
                async for _topic, payload in sub:
                    try:
                        pub.publish(RobotState.from_bytes(payload))
                    except BusError as exc:  # one bad sample is skipped, never fatal; said once
                        bad += 1
                        if bad == 1:
                            log.warning("skipping a robot.state sample that does not decode: %s", exc)

            task = asyncio.create_task(follow(), name="ros2-joint-states")
            stopped = asyncio.create_task(stop.wait())
            await asyncio.wait({task, stopped}, return_when=asyncio.FIRST_COMPLETED)
            for t in (task, stopped):
                t.cancel()
            await asyncio.gather(task, stopped, return_exceptions=True)
            if task.done() and not task.cancelled() and task.exception() is not None:
                raise task.exception()  # type: ignore[misc]
            log.info("published %d JointState samples, skipped %d", pub.published, bad)
    finally:
        pub.close()
        zb.close_session()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from aioadept.cli.options import setup_logging

    setup_logging(args.log_level)
    try:
        _key, opts = _options(args)
    except ValueError as exc:   # one line naming the option, no usage block
        print(f"aioadept ros2: {exc}", file=sys.stderr)
        return 2
    from aioadept.cli.options import run_node

    return run_node("aioadept ros2", run(args, opts))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
