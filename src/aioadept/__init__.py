"""aioadept: event-driven control of Adept/Omron V+ robots.

The data path, as the package tree reads: ``protocol`` (sans-IO line protocol) → ``client`` (asyncio RobotClient)
→ ``sim`` (simulated controller) → ``bus`` (ZeroMQ + Protobuf) → ``vision`` → ``apps`` → ``analysis``.
"""

from aioadept.commands import (
    Break,
    Command,
    DisableAir,
    EnableAir,
    Here,
    Joined,
    MoveJoints,
    MoveRelJoints,
    MoveRelTool,
    MoveRelWorld,
    MoveTo,
    MoveToolZ,
    SetSpeed,
    Skill,
)
from aioadept.commands import CloseHand, OpenHand, RelaxHand, Sig, Signal, WaitSig  # digital I/O and the hand
from aioadept.geometry import Pose

__version__ = "0.1.0"

__all__ = [
    "Break", "Command", "DisableAir", "EnableAir", "Here", "Joined", "MoveJoints", "MoveRelJoints", "MoveRelTool",
    "MoveRelWorld", "MoveTo", "MoveToolZ", "Pose", "SetSpeed", "Skill", "__version__",
    "CloseHand", "OpenHand", "RelaxHand", "Sig", "Signal", "WaitSig",
]
