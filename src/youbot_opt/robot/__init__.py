"""What a robot is (layer L1): parameters, URDF, the loaded model and how to load it again.

Modules: :mod:`.params`, :mod:`.urdf`, :mod:`.model` (:class:`RobotModel`,
its bounds and kinematics), :mod:`.catalogue` (the robots known by name),
:mod:`.load` (``load_model``), :mod:`.source` (:class:`RobotSource`, how result
files name their robot), :mod:`.mimic` and the hostile-URDF policy :mod:`.urdf_check`.
The names here are imported on first use, so importing
``youbot_opt.robot.params`` does not import Pinocchio.

    from youbot_opt.robot import RobotSource
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from youbot_opt.robot.source import RobotSource, urdf_digest

__all__ = ["RobotSource", "urdf_digest"]


def __getattr__(name: str) -> Any:
    """Import :mod:`.source` when one of its names is first used (PEP 562)."""
    if name in __all__:
        return getattr(importlib.import_module("youbot_opt.robot.source"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
