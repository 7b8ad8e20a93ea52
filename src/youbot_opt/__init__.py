"""youbot_opt: Pinocchio-backed trajectory and IK-path optimisation with CasADi.

The public API is re-exported here; see the README for a tour.
"""

from __future__ import annotations

import logging

from youbot_opt.exceptions import (
    FrameNotFound,
    ModelError,
    ParameterError,
    ResultFileError,
    RobotNotFound,
    SolveFailed,
    TranscriptionError,
    UnreachableTarget,
    YoubotOptError,
    YoubotOptWarning,
)

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "__version__",
    "FrameNotFound",
    "ModelError",
    "ParameterError",
    "ResultFileError",
    "RobotNotFound",
    "SolveFailed",
    "TranscriptionError",
    "UnreachableTarget",
    "YoubotOptError",
    "YoubotOptWarning",
]
