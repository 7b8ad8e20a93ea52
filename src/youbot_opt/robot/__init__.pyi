"""Public names of :mod:`youbot_opt.robot`, listed once (read by ``lazy_loader``)."""

from .source import RobotSource as RobotSource, urdf_digest as urdf_digest
