"""aioadept: event-driven control of Adept/Omron V+ robots.

The data path, as the package tree reads: ``protocol`` (sans-IO line protocol) → ``client`` (asyncio RobotClient)
→ ``sim`` (simulated controller) → ``bus`` (ZeroMQ + Protobuf) → ``vision`` → ``apps`` → ``analysis``.
"""

__version__ = "0.1.0"

_COMMANDS = frozenset((
    "Appro", "Appros", "Break", "CloseHand", "Command", "Depart", "Departs", "DisableAir", "EnableAir", "GetStatus",
    "Here", "Joined", "MoveJoints", "MoveRelJoints", "MoveRelTool", "MoveRelToolS", "MoveRelWorld", "MoveTo",
    "MoveToS", "MoveToolZ", "OpenHand", "RelaxHand", "SetSpeed", "Sig", "Signal", "Skill", "WaitSig"))


def __getattr__(name: str):
    # Every name is imported on first use, so that importing aioadept (every subcommand does, and every module of
    # the package) costs nothing: the commands and the pose bring numpy, RobotClient asyncio and the transport.
    if name in _COMMANDS:
        from aioadept import commands

        return getattr(commands, name)
    if name == "Pose":
        from aioadept.geometry import Pose

        return Pose
    if name == "RobotClient":
        from aioadept.client import RobotClient

        return RobotClient
    raise AttributeError(f"module 'aioadept' has no attribute {name!r}")


__all__ = [
    "Appro", "Appros", "Break", "CloseHand", "Command", "Depart", "Departs", "DisableAir", "EnableAir",
    "GetStatus", "Here", "Joined", "MoveJoints", "MoveRelJoints", "MoveRelTool", "MoveRelToolS", "MoveRelWorld",
    "MoveTo", "MoveToS", "MoveToolZ", "OpenHand", "Pose", "RelaxHand", "RobotClient", "SetSpeed", "Sig",
    "Signal", "Skill", "WaitSig", "__version__"
]
