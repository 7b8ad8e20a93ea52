"""CasADi forward/inverse dynamics of fixed-base Pinocchio models.

``build_dynamics(model, backend)`` returns a :class:`Dynamics` holding the named
CasADi Functions ``forward_dynamics`` (q, v, tau) -> a and ``inverse_dynamics``
(q, v, a) -> tau, with the model's joint damping applied in both. The
``"symbolic"`` backend transcribes Pinocchio's algorithms into SX expressions
(:mod:`youbot_opt.dynamics.symbolic`); the ``"pinocchio"`` backend calls
Pinocchio through CasADi Callbacks (:mod:`youbot_opt.dynamics.callback`).
Continuous joints enter in angle coordinates (one unbounded angle each):
:mod:`youbot_opt.dynamics.coordinates` converts to and from Pinocchio's (cos, sin).
"""

from __future__ import annotations

from youbot_opt.dynamics.base import BACKENDS, Dynamics, available_backends, build_dynamics
from youbot_opt.dynamics.coordinates import (
    angle_model,
    angle_robot,
    from_pin_configuration,
    to_pin_configuration,
)
from youbot_opt.dynamics.symbolic import SymbolicModel, build_symbolic_model
from youbot_opt.dynamics.tree import SUPPORTED_JOINTS

__all__ = [
    "BACKENDS",
    "SUPPORTED_JOINTS",
    "Dynamics",
    "SymbolicModel",
    "angle_model",
    "angle_robot",
    "available_backends",
    "build_dynamics",
    "build_symbolic_model",
    "from_pin_configuration",
    "to_pin_configuration",
]
