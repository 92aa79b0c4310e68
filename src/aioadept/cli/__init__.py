"""The ``aioadept`` console script: one entry point, one subcommand per node or tool.

Each subcommand is one module of this package (``cli/sim.py``, ``cli/send.py``, ...) exposing ``main(argv) -> int``;
they share one options layer (:mod:`aioadept.cli.options`). This module only dispatches, and imports a subcommand's
module when it is called so ``aioadept --help`` stays fast.
"""

from __future__ import annotations

import importlib
import sys

from aioadept.cli.options import DefaultsHelpFormatter, description  # noqa: F401  (public names)

# name -> (module with main(argv), one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "sim": ("aioadept.cli.sim", "run the simulated Adept controller (RobotServer) over TCP"),
    "state": ("aioadept.cli.state", "relay a V+ controller's state stream onto the robot.state topic"),
    "bridge": ("aioadept.cli.bridge", "share one robot connection between applications over Zenoh"),
    "ros2": ("aioadept.cli.ros2", "put the robot state as a ROS 2 JointState on rmw_zenoh's key expression"),
    "opcua": ("aioadept.cli.opcua", "serve the robot as an OPC UA server (Robotics companion specification)"),
    "send": ("aioadept.cli.send", "send commands to a robot server and print the acks"),
    "vision": ("aioadept.cli.vision", "run the image acquisition + processing node"),
    "focus": ("aioadept.cli.focus", "run focus-plane calibration against a robot server and vision node"),
    "demo": ("aioadept.cli.demo", "start the whole simulated cell and run focus calibration"),
    "pickplace": ("aioadept.cli.pickplace", "pick parts from the feeder and place them on the pallet, vision-guided"),
    "analyze": ("aioadept.cli.analyze", "analyse run folders: the paper's timing metrics and plots"),
    "experiment": ("aioadept.cli.experiment", "repeat the demo over a parameter grid, then analyse"),
    "vplus": ("aioadept.cli.vplus", "V+ source tools: check files, serve the V+ language server"),
    "calibrate": ("aioadept.cli.calibrate", "estimate the fixed camera's pose in the robot base frame (marker on "
                                            "the tool)"),
}


EXTRAS: dict[str, str] = {"cv2": "vision", "scipy": "analysis", "matplotlib": "analysis", "asyncua": "opcua",
                         "pygls": "lsp", "lsprotocol": "lsp"}
"""Top-level modules of the optional extras (pyproject.toml) -> the extra that installs them."""


def missing_extra(exc: ModuleNotFoundError) -> str | None:
    """The one line telling which extra to install, when ``exc`` is a module of an extra; else None."""
    top = (exc.name or "").split(".")[0]
    extra = EXTRAS.get(top)
    if extra is None:
        return None
    return f"needs the {extra!r} extra ({top} is not installed): pip install 'aioadept[{extra}]'"


def _usage() -> str:
    lines = ["usage: aioadept COMMAND [options]", "", "commands:"]
    lines += [f"  {name:<11} {help_}" for name, (_, help_) in SUBCOMMANDS.items()]
    lines += ["", "Run 'aioadept COMMAND --help' for a command's options."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        print(_usage())
        return 0 if args else 2
    if args[0] == "--version":
        from aioadept import __version__

        print(__version__)
        return 0
    name = args[0]
    if name not in SUBCOMMANDS:
        print(f"aioadept: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    module_name = SUBCOMMANDS[name][0]
    try:
        module = importlib.import_module(module_name)
        return int(module.main(args[1:]) or 0)
    except ModuleNotFoundError as exc:
        if exc.name == module_name:
            print(f"aioadept: {name} is not available in this version", file=sys.stderr)
            return 2
        hint = missing_extra(exc)
        if hint is None:
            raise
        print(f"aioadept {name}: {hint}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
