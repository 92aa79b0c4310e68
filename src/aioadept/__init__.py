"""aioadept: event-driven control of Adept/Omron V+ robots.

The data path, as the package tree reads: ``protocol`` (sans-IO line protocol) → ``client`` (asyncio RobotClient)
→ ``sim`` (simulated controller) → ``bus`` (ZeroMQ + Protobuf) → ``vision`` → ``apps`` → ``analysis``.
"""

from aioadept.client import RobotClient
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

__all__ = [
    "Appro", "Appros", "Break", "CloseHand", "Command", "Depart", "Departs", "DisableAir", "EnableAir",
    "GetStatus", "Here", "Joined", "MoveJoints", "MoveRelJoints", "MoveRelTool", "MoveRelToolS", "MoveRelWorld",
    "MoveTo", "MoveToS", "MoveToolZ", "OpenHand", "Pose", "RelaxHand", "RobotClient", "SetSpeed", "Sig",
    "Signal", "Skill", "WaitSig", "__version__"
]
