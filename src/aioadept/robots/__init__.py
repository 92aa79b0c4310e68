"""Robot models as values, chosen by name: kinematics, limits, speeds, home pose and URDF of each arm.

Pure numpy, no I/O. One module per kinematic family holds its formulas and per-model constants
(:mod:`aioadept.robots.viper`: Viper s650, s850; :mod:`aioadept.robots.scara`: Cobra s600, s800);
:func:`model` hands a model out by name, so the simulator, the world, the recorder and the URDF ask the model and
nothing else knows which arm runs. Both the simulated controller (:mod:`aioadept.sim`) and the vision side's
virtual camera use it, so it lives below both of them: neither has to import the other.

Every model has: ``name``, ``family`` (``"viper"``/``"scara"``), ``dof``, ``prismatic`` (per joint), ``limits``
(:class:`~aioadept.robots.base.JointLimits`), ``max_speed_deg_s``, ``home_deg``, ``reach_mm``, ``urdf_joints``;
and ``flange_matrix``, ``flange_matrices``, ``forward``, ``inverse``, ``configuration``, ``check_joint_path``,
``describe``. Their figures and sources: docs/sim.md, "Robot models".
"""

from __future__ import annotations

from typing import Union

import numpy as np

from aioadept.robots import viper_s850_batch
from aioadept.robots.scara import COBRA_S600, COBRA_S800, Scara
from aioadept.robots.viper import VIPER_S650, VIPER_S850, Viper

RobotModel = Union[Viper, Scara]  # noqa: UP007

MODELS: dict[str, RobotModel] = {m.name: m for m in (VIPER_S850, VIPER_S650, COBRA_S600, COBRA_S800)}
"""Every model by name."""

DEFAULT_MODEL = "viper-s850"


def model(name: str = DEFAULT_MODEL) -> RobotModel:
    """The robot model called ``name``; ``ValueError`` naming the known ones for any other name."""
    try:
        return MODELS[name]
    except KeyError:
        raise ValueError(f"unknown robot model {name!r} (known: {', '.join(MODELS)})") from None


def all_solutions(m: RobotModel, flanges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every closed-form inverse solution of N flange transforms at once: joints (N, B, dof), one per
    configuration (a Viper's 8 in :data:`~aioadept.robots.viper_s850_batch.BRANCHES` order, a SCARA's RIGHTY then
    LEFTY), and ``reached`` (N, B)."""
    if isinstance(m, Viper):
        sols = viper_s850_batch.solutions(np.asarray(flanges, dtype=float), model=m)
        return sols.joints_deg, sols.reached
    return m.all_solutions(flanges)


__all__ = ["DEFAULT_MODEL", "MODELS", "RobotModel", "all_solutions", "model"]
