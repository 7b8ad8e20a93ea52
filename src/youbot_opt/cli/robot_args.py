"""The ``--robot`` options shared by every command that loads a robot.

:func:`add_robot_arguments` adds ``--robot NAME|PATH``, ``--package-dir DIR``
(repeatable), ``--lenient``, ``--lock NAME=VALUE`` (repeatable) and
``--tip-frame F``; :func:`load_robot` turns them into
:func:`youbot_opt.robot.load.load_model` arguments. Building the parser
imports no Pinocchio (``--help`` stays fast); ``youbot-opt robots`` lists the
names.
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # Pinocchio is imported in load_robot, so --help stays fast
    from youbot_opt.robot.model import RobotModel

__all__ = [
    "add_loading_options",
    "add_robot_arguments",
    "is_study_youbot",
    "load_robot",
    "loading_options",
    "parse_lock",
]


def parse_lock(text: str) -> tuple[str, float]:
    """Parse one ``--lock NAME=VALUE`` (VALUE in [rad] or [m]).

    Parameters
    ----------
    text : str
        ``"joint_name=0.5"``.

    Returns
    -------
    tuple of (str, float)
        The joint name and its position.

    Raises
    ------
    argparse.ArgumentTypeError
        If ``text`` is not ``NAME=VALUE`` with a finite number.
    """
    name, sep, value = text.rpartition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not sep or not name.strip() or not math.isfinite(number):
        raise argparse.ArgumentTypeError(
            f"expected NAME=VALUE with a finite VALUE in rad (or m), got {text!r}"
        )
    return name.strip(), number


def add_loading_options(group: argparse._ActionsContainer) -> None:
    """Add ``--package-dir``, ``--lenient`` and ``--lock`` (how a named robot is loaded).

    Parameters
    ----------
    group : argparse parser or argument group
        Where the options go (``ikpath`` has its own ``--robot`` and ``--frame``).
    """
    group.add_argument(
        "--package-dir",
        action="append",
        default=[],
        metavar="DIR",
        help="folder for package:// mesh references (repeatable; example-robot-data's are "
        "found automatically)",
    )
    group.add_argument(
        "--lenient",
        action="store_true",
        help="load implausible inertias on moving links with a warning instead of refusing",
    )
    group.add_argument(
        "--lock",
        action="append",
        default=[],
        type=parse_lock,
        metavar="NAME=VALUE",
        help="lock a joint at a position in rad or m (repeatable)",
    )


def loading_options(args: argparse.Namespace) -> dict[str, object]:
    """Keyword arguments of ``load_model`` from the options of :func:`add_loading_options`.

    Raises
    ------
    ParameterError
        If ``--lock`` names a joint twice.
    """
    from youbot_opt.exceptions import ParameterError

    names = [name for name, _ in args.lock]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ParameterError(f"--lock gives joints {twice} more than once", name="lock")
    return {
        "package_dirs": tuple(args.package_dir),
        "strict": not args.lenient,
        "lock_joints": dict(args.lock) if args.lock else None,
    }


def add_robot_arguments(parser: argparse.ArgumentParser, *, default: str = "youbot") -> None:
    """Add ``--robot``, ``--package-dir``, ``--lenient``, ``--lock`` and ``--tip-frame``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The sub-command's parser.
    default : str
        Default ``--robot``.
    """
    group = parser.add_argument_group("robot")
    group.add_argument(
        "--robot",
        default=default,
        metavar="NAME|PATH",
        help=f"robot name (`youbot-opt robots` lists them) or URDF path (default: {default})",
    )
    add_loading_options(group)
    group.add_argument(
        "--tip-frame", default=None, metavar="F", help="end-effector frame (default: the robot's)"
    )


def is_study_youbot(args: argparse.Namespace) -> bool:
    """Return True when the options select the study's planar youBot arm, unchanged."""
    return args.robot == "youbot" and not args.lock and args.tip_frame is None


def load_robot(args: argparse.Namespace, *, damping: float | None = None) -> RobotModel:
    """Load the robot the options of :func:`add_robot_arguments` describe.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options.
    damping : float, optional
        Joint damping override in [N m s/rad].

    Returns
    -------
    RobotModel
        The robot.

    Raises
    ------
    RobotNotFound, ModelError, FrameNotFound, ParameterError
        As :func:`youbot_opt.robot.load.load_model`; a joint locked twice
        raises ParameterError.
    """
    from youbot_opt.cli.warning_lines import flush_warnings
    from youbot_opt.robot.load import load_model

    robot = load_model(
        args.robot,
        tip_frame=args.tip_frame,
        damping=damping,
        **loading_options(args),  # type: ignore[arg-type]
    )
    flush_warnings()  # the loader's warnings, grouped, before the run
    return robot
