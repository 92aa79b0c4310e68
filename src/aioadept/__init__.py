"""aioadept: event-driven control of Adept/Omron V+ robots.

The data path, as the package tree reads: ``protocol`` (sans-IO line protocol) → ``client`` (asyncio RobotClient)
→ ``sim`` (simulated controller) → ``bus`` (ZeroMQ + Protobuf) → ``vision`` → ``apps`` → ``analysis``.
"""

from aioadept.commands import (
    Appro,
    Appros,
    Break,
    CloseHand,
    Command,
    Depart,
    Departs,
    DisableAir,
    EnableAir,
    GetStatus,
    Here,
    Joined,
    MoveJoints,
    MoveRelJoints,
    MoveRelTool,
    MoveRelToolS,
    MoveRelWorld,
    MoveTo,
    MoveToS,
    MoveToolZ,
    OpenHand,
    RelaxHand,
    SetSpeed,
    Sig,
    Signal,
    Skill,
    WaitSig,
)
from aioadept.geometry import Pose

__version__ = "0.1.0"


def __getattr__(name: str):
    # RobotClient is imported on first use, so that importing aioadept (every subcommand does) stays as light as
    # the commands and the pose: the client brings asyncio and the transport.
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
