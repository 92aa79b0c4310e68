"""The simulated Adept controller: a SmartController with a Viper s850 running AdeptServer (``aioadept sim``).

Layers, from pure to I/O (see docs/sim.md)::

    kinematics   Viper s850 forward/inverse kinematics, joint limits, reach       (pure numpy)
    motion       synchronised trapezoidal joint profiles, blending, stop            (pure, time passed in)
    controller   skill table, serial executor, V+ semantics, error acks             (pure, time passed in)
    server       asyncio TCP adapter, clock, faults, robot-state publisher
    __main__     the ``aioadept sim`` command

In-process use for tests: :func:`aioadept.testing.sim.running_sim`.
"""

from aioadept.sim.controller import Controller
from aioadept.sim.skills import SkillResult, SkillSpec
from aioadept.robots.viper_s850 import HOME_JOINTS_DEG, forward, inverse
from aioadept.sim.server import Faults, SimOptions, SimServer

__all__ = ["HOME_JOINTS_DEG", "Controller", "Faults", "SimOptions", "SimServer", "SkillResult", "SkillSpec",
           "forward", "inverse"]
