"""Export a plan to a controller: samples at its rate, then CSV, JSON or ROS 2.

:func:`sample_trajectory` (or ``result.sample(rate_hz)``) evaluates the
transcription's own interpolants on the controller's clock
(:class:`SampledTrajectory`); :mod:`~youbot_opt.trajopt.export.files` writes
CSV and JSON, :mod:`~youbot_opt.trajopt.export.ros2` a ``JointTrajectory``
message file and a rosbag2 (``rosbags``, optional). Each writer has its reader,
for round trips. Guide: docs/export.md.

>>> write_csv(result.sample(500.0), "plan.csv")  # doctest: +SKIP
"""

from youbot_opt.trajopt.export.files import read_csv, read_json, write_csv, write_json
from youbot_opt.trajopt.export.ros2 import (
    read_ros2_message,
    read_rosbag,
    write_ros2_message,
    write_rosbag,
)
from youbot_opt.trajopt.export.samples import (
    SampledTrajectory,
    coordinate_names,
    sample_trajectory,
)

__all__ = [
    "SampledTrajectory",
    "coordinate_names",
    "read_csv",
    "read_json",
    "read_ros2_message",
    "read_rosbag",
    "sample_trajectory",
    "write_csv",
    "write_json",
    "write_ros2_message",
    "write_rosbag",
]
