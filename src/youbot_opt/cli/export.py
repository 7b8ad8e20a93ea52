"""``youbot-opt export``: a run's plan at a controller's rate, as CSV, JSON or ROS 2.

Usage::

    youbot-opt export RUN_FOLDER [--format csv|json|ros2|rosbag] [--rate HZ]
                      [--out PATH] [--topic TOPIC] [--allow-failed]

RUN_FOLDER is a run folder holding ``result.npz`` (or the ``.npz`` file itself);
the result is loaded by :func:`youbot_opt.trajopt.io.load_result`, which
re-checks it against its robot model. The samples come from the plan's own
interpolants (:meth:`TrajOptResult.sample`). Formats: docs/export.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from youbot_opt.exceptions import ParameterError

__all__ = ["FORMATS", "SUFFIXES", "run_export"]

FORMATS: tuple[str, ...] = ("csv", "json", "ros2", "rosbag")
"""Output formats: CSV, JSON, a ROS 2 JointTrajectory message file, a rosbag2 folder."""
SUFFIXES: dict[str, str] = {"csv": ".csv", "json": ".json", "ros2": ".ros2.json", "rosbag": "_bag"}
"""Default output name of each format, after ``trajectory_<rate>hz``."""


def _result_file(run: Path) -> Path:
    """Return the result file of a run folder (or the file given)."""
    if run.is_file():
        return run
    if not run.is_dir():
        raise ParameterError(f"run folder {run} does not exist", name="RUN_FOLDER", value=str(run))
    single = run / "result.npz"
    if single.is_file():
        return single
    many = sorted((run / "results").glob("*.npz")) if (run / "results").is_dir() else []
    listed = ", ".join(str(p) for p in many[:10]) if many else "none"
    raise ParameterError(
        f"{run} holds no result.npz; pass one result file instead (found: {listed})",
        name="RUN_FOLDER",
        value=str(run),
    )


def run_export(args: argparse.Namespace) -> int:
    """Export the plan of a run folder; print what was written.

    Parameters
    ----------
    args : argparse.Namespace
        ``run`` (path), ``format`` (one of :data:`FORMATS`), ``rate`` [Hz],
        ``out`` (path or None: ``<run>/trajectory_<rate>hz<suffix>``),
        ``topic`` (rosbag topic) and ``allow_failed`` (export a result whose
        re-check failed).

    Returns
    -------
    int
        0 when the file was written.

    Raises
    ------
    ParameterError
        Unknown format, bad rate, no result in the folder, a failed result
        without ``allow_failed``, or ``rosbags`` missing for ``rosbag``.
    ResultFileError
        If the result cannot be loaded or the output cannot be written.
    """
    from youbot_opt.trajopt.export import write_csv, write_json, write_ros2_message, write_rosbag
    from youbot_opt.trajopt.export.ros2 import DEFAULT_TOPIC
    from youbot_opt.trajopt.io import load_result

    fmt = str(args.format)
    if fmt not in FORMATS:
        raise ParameterError(f"--format must be one of {FORMATS}, got {fmt!r}", name="format")
    path = _result_file(Path(args.run))
    result = load_result(path)
    if not result.success and not getattr(args, "allow_failed", False):
        raise ParameterError(
            f"{path}: the result did not pass its check on load (status "
            f"{result.status.value}: {result.message}); pass --allow-failed to export it anyway",
            name="RUN_FOLDER",
        )
    samples = result.sample(args.rate)
    folder = path.parent
    out = getattr(args, "out", None)
    rate = f"{samples.rate_hz:g}".replace(".", "p")
    target = Path(out) if out else folder / f"trajectory_{rate}hz{SUFFIXES[fmt]}"
    if fmt == "csv":
        written = write_csv(samples, target)
    elif fmt == "json":
        written = write_json(samples, target)
    elif fmt == "ros2":
        written = write_ros2_message(samples, target)
    else:
        topic = getattr(args, "topic", None) or DEFAULT_TOPIC
        written = write_rosbag(samples, target, topic=topic)
    print(
        f"{written}: {samples.n_samples} samples at {samples.rate_hz:g} Hz over "
        f"{samples.duration:.4g} s ({samples.interpolation} interpolant, joints "
        f"{', '.join(samples.joint_names)}; result status {result.status.value})"
    )
    return 0
