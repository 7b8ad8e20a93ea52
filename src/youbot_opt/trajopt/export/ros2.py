"""Samples as a ROS 2 ``trajectory_msgs/msg/JointTrajectory``: a message file and a rosbag2.

The message file is JSON written so that it is also the YAML that
``ros2 topic pub /joint_trajectory trajectory_msgs/msg/JointTrajectory "$(cat plan.json)"``
reads (every float has a decimal point, as YAML 1.1 wants). One point per
sample: positions, velocities, accelerations and efforts in SI units (rad, m,
N m, N: the ROS convention and ours), ``time_from_start`` to the nanosecond.
The rosbag2 (one message on one topic, sqlite3 storage) is written by the
pure-Python ``rosbags`` package (``pip install rosbags``), no ROS install needed.

>>> write_ros2_message(result.sample(500.0), "plan.json")  # doctest: +SKIP
>>> write_rosbag(result.sample(500.0), "plan_bag")  # doctest: +SKIP
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from youbot_opt._files import atomic_write_text
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptError
from youbot_opt.robot.model import REVOLUTE_UNITS
from youbot_opt.trajopt.export.files import read_json_document, writable_target
from youbot_opt.trajopt.export.samples import SampledTrajectory

__all__ = [
    "MESSAGE_TYPE",
    "DEFAULT_TOPIC",
    "read_ros2_message",
    "read_rosbag",
    "write_ros2_message",
    "write_rosbag",
]

MESSAGE_TYPE = "trajectory_msgs/msg/JointTrajectory"
"""The ROS 2 message type written."""
DEFAULT_TOPIC = "/joint_trajectory"
"""Topic in a rosbag2 (a joint_trajectory_controller reads ``~/joint_trajectory``)."""
_NS = 1_000_000_000  # nanoseconds per second
_INSTALL = "pip install rosbags (or pip install 'youbot_opt[ros2]')"


def _duration(t: float) -> dict[str, int]:
    sec, nanosec = divmod(int(round(float(t) * _NS)), _NS)
    return {"sec": int(sec), "nanosec": int(nanosec)}


def _seconds(stamp: Any, source: str) -> float:
    if isinstance(stamp, dict):
        sec, nanosec = stamp.get("sec"), stamp.get("nanosec")
    else:
        sec, nanosec = getattr(stamp, "sec", None), getattr(stamp, "nanosec", None)
    if not isinstance(sec, int | np.integer) or not isinstance(nanosec, int | np.integer):
        raise ResultFileError(f"{source}: time_from_start must have integer sec and nanosec")
    return float(sec) + float(nanosec) / _NS


def _number(x: float) -> str:
    """Return a float as JSON that YAML 1.1 also reads as a float (a '.' in the mantissa)."""
    text = repr(float(x))
    mantissa, e, exponent = text.partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return f"{mantissa}{e}{exponent}"


def _floats(row: Array) -> str:
    return "[" + ", ".join(_number(x) for x in row) + "]"


def write_ros2_message(samples: SampledTrajectory, path: str | os.PathLike[str]) -> Path:
    """Write ``samples`` as one ``JointTrajectory`` message (JSON that is also ROS 2 YAML).

    Parameters
    ----------
    samples : SampledTrajectory
        The samples; one trajectory point each.
    path : str or path-like
        Target file; its folder must exist.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ResultFileError
        If the folder does not exist.
    """
    target = writable_target(path)
    points = []
    for i in range(samples.n_samples):
        stamp = _duration(samples.time[i])
        points.append(
            "    {"
            f'"positions": {_floats(samples.q[i])}, '
            f'"velocities": {_floats(samples.v[i])}, '
            f'"accelerations": {_floats(samples.a[i])}, '
            f'"effort": {_floats(samples.tau[i])}, '
            f'"time_from_start": {{"sec": {stamp["sec"]}, "nanosec": {stamp["nanosec"]}}}'
            "}"
        )
    text = (
        "{\n"
        '  "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},\n'
        f'  "joint_names": {json.dumps(list(samples.joint_names))},\n'
        '  "points": [\n' + ",\n".join(points) + "\n  ]\n}\n"
    )
    atomic_write_text(target, text)
    return target


def _from_message(names: Any, points: list[Any], source: str, get: Any) -> SampledTrajectory:
    """Return the samples of a message's joint names and points (``get(point, field)``)."""
    if len(points) < 2:
        raise ResultFileError(f"{source}: a trajectory needs >= 2 points, got {len(points)}")
    try:
        time = np.array([_seconds(get(p, "time_from_start"), source) for p in points])
        arrays = {
            field: np.array([np.asarray(get(p, field), dtype=float) for p in points])
            for field in ("positions", "velocities", "accelerations", "effort")
        }
        names = tuple(str(n) for n in names)
        return SampledTrajectory(
            time=time,
            q=arrays["positions"],
            v=arrays["velocities"],
            a=arrays["accelerations"],
            tau=arrays["effort"],
            joint_names=names,
            units=(REVOLUTE_UNITS,) * len(names),
            rate_hz=1.0 / float(time[1] - time[0]),
        )
    except (KeyError, TypeError, ValueError, YoubotOptError) as exc:
        raise ResultFileError(f"{source}: malformed JointTrajectory ({exc!r})") from exc


def read_ros2_message(path: str | os.PathLike[str]) -> SampledTrajectory:
    """Read a message file written by :func:`write_ros2_message`.

    A ROS message carries no units: every joint is read as revolute (rad), and
    the rate is ``1 / (time[1] - time[0])``.

    Raises
    ------
    ResultFileError
        If the file is missing, not JSON, or not a ``JointTrajectory``.
    """
    source = str(path)
    doc = read_json_document(path)
    if not isinstance(doc, dict) or "points" not in doc or "joint_names" not in doc:
        raise ResultFileError(f"{source}: not a JointTrajectory (no joint_names and points)")
    return _from_message(doc["joint_names"], list(doc["points"]), source, lambda p, f: p[f])


def _rosbags() -> tuple[ModuleType, ModuleType]:
    """Return ``rosbags.rosbag2`` and ``rosbags.typesys``, or raise saying how to install them."""
    try:
        import rosbags.rosbag2 as rosbag2
        import rosbags.typesys as typesys
    except ImportError as exc:
        raise ParameterError(
            f"writing or reading a rosbag2 needs the rosbags package: {_INSTALL}", name="format"
        ) from exc
    return rosbag2, typesys


def write_rosbag(
    samples: SampledTrajectory,
    path: str | os.PathLike[str],
    *,
    topic: str = DEFAULT_TOPIC,
) -> Path:
    """Write ``samples`` as a rosbag2 folder holding one ``JointTrajectory`` message.

    Parameters
    ----------
    samples : SampledTrajectory
        The samples.
    path : str or path-like
        The bag folder to create; it must not exist, its parent must. The bag
        is written beside it and renamed into place, so a kill leaves no half bag.
    topic : str, optional
        The message's topic.

    Returns
    -------
    Path
        The bag folder.

    Raises
    ------
    ParameterError
        If ``rosbags`` is not installed (the message says how to install it).
    ResultFileError
        If ``path`` exists or its parent does not.
    """
    rosbag2, typesys = _rosbags()
    target = Path(path)
    if target.exists():
        raise ResultFileError(
            f"cannot write rosbag {target}: it exists; remove it or choose another"
        )
    writable_target(target)
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    types = store.types
    message = types[MESSAGE_TYPE](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=""
        ),
        joint_names=list(samples.joint_names),
        points=[
            types["trajectory_msgs/msg/JointTrajectoryPoint"](
                positions=np.array(samples.q[i]),
                velocities=np.array(samples.v[i]),
                accelerations=np.array(samples.a[i]),
                effort=np.array(samples.tau[i]),
                time_from_start=types["builtin_interfaces/msg/Duration"](
                    **_duration(samples.time[i])
                ),
            )
            for i in range(samples.n_samples)
        ],
    )
    scratch = Path(tempfile.mkdtemp(prefix=f".tmp-{target.name}.", dir=target.parent))
    try:
        staged = scratch / target.name
        with rosbag2.Writer(staged, version=8) as writer:
            connection = writer.add_connection(topic, MESSAGE_TYPE, typestore=store)
            writer.write(connection, 0, store.serialize_cdr(message, MESSAGE_TYPE))
        os.replace(staged, target)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return target


def read_rosbag(path: str | os.PathLike[str], *, topic: str = DEFAULT_TOPIC) -> SampledTrajectory:
    """Read the first ``JointTrajectory`` on ``topic`` of a rosbag2 written by :func:`write_rosbag`.

    Raises
    ------
    ParameterError
        If ``rosbags`` is not installed.
    ResultFileError
        If the bag cannot be read or has no such message.
    """
    rosbag2, typesys = _rosbags()
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    source = str(path)
    try:
        with rosbag2.Reader(Path(path)) as reader:
            connections = [c for c in reader.connections if c.topic == topic]
            for connection, _, raw in reader.messages(connections=connections):
                message = store.deserialize_cdr(raw, connection.msgtype)
                break
            else:
                raise ResultFileError(f"{source}: no message on topic {topic!r}")
    except (rosbag2.ReaderError, OSError, KeyError, ValueError) as exc:
        raise ResultFileError(f"cannot read rosbag {source}: {exc}") from exc
    return _from_message(message.joint_names, list(message.points), source, getattr)
