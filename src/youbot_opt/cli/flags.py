"""What the parsed flags mean to the library: the robot, IPOPT's options, the Dask scheduler.

:func:`load_robot` loads the robot of ``--robot``, ``--package-dir``,
``--lenient``, ``--lock`` and ``--tip-frame`` (:func:`loading_options`: the
keywords of :func:`~youbot_opt.robot.load.load_model`); :func:`clearance_of`
reads ``--scene`` and its companions; :func:`ipopt_options`
reads ``--max-iter`` and ``--linear-solver``; :func:`scheduler_address` turns
``--scheduler`` / ``--scheduler-file`` into the address a sweep connects to
(``None``: the local pool; guide: ``docs/scaling.md``); :func:`report_shard`
prints what a ``--shard I/K`` run did.

    sweep = SweepOptions(executor=scheduler_address(args) or "process", out=folder)
"""

from __future__ import annotations

import argparse
import sys
from typing import TypedDict

from youbot_opt.cli.warning_lines import flush_warnings
from youbot_opt.collision.clearance import Clearance
from youbot_opt.collision.pairs import self_collision_pairs
from youbot_opt.collision.scene import Scene
from youbot_opt.collision.scene_file import load_scene
from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.payload import Payload
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.sweeps.scheduler import (
    check_scheduler_address,
    is_scheduler_address,
    read_scheduler_file,
)

__all__ = [
    "LoadingOptions",
    "clearance_of",
    "ipopt_options",
    "is_study_youbot",
    "load_robot",
    "loading_options",
    "report_shard",
    "scheduler_address",
]


class LoadingOptions(TypedDict):
    """The keywords of :func:`~youbot_opt.robot.load.load_model` that the loading flags set."""

    package_dirs: tuple[str, ...]
    strict: bool
    lock_joints: dict[str, float] | None


def loading_options(args: argparse.Namespace) -> LoadingOptions:
    """Return ``load_model``'s keywords of ``--package-dir``, ``--lenient`` and ``--lock``.

    Raises
    ------
    ParameterError
        If ``--lock`` names a joint twice.
    """
    names = [name for name, _ in args.lock]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ParameterError(f"--lock gives joints {twice} more than once", name="lock")
    return {
        "package_dirs": tuple(args.package_dir),
        "strict": not args.lenient,
        "lock_joints": dict(args.lock) if args.lock else None,
    }


def is_study_youbot(args: argparse.Namespace) -> bool:
    """Return True when the options select the study's planar youBot arm, unchanged."""
    return args.robot == "youbot" and not args.lock and args.tip_frame is None


def load_robot(args: argparse.Namespace, *, damping: float | None = None) -> RobotModel:
    """Load the robot of ``--robot``, ``--package-dir``, ``--lenient``, ``--lock``, ``--tip-frame``.

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
    robot = load_model(
        args.robot,
        tip_frame=args.tip_frame,
        damping=damping,
        payload=payload_of(args),
        defer_visual=True,  # meshes read where the replay is drawn (another process)
        **loading_options(args),
    )
    flush_warnings()  # the loader's warnings, grouped, before the run
    return robot


def payload_of(args: argparse.Namespace) -> Payload | None:
    """Return the :class:`Payload` of ``--payload-mass/-com/-inertia/-frame`` (None: no mass).

    Raises
    ------
    ParameterError
        If a payload flag is given without ``--payload-mass``, or a value is
        not a rigid body's (as :class:`~youbot_opt.robot.payload.Payload`).
    """
    mass = getattr(args, "payload_mass", None)
    others = {
        "--payload-com": getattr(args, "payload_com", None),
        "--payload-inertia": getattr(args, "payload_inertia", None),
        "--payload-frame": getattr(args, "payload_frame", None),
    }
    if mass is None:
        given = [flag for flag, value in others.items() if value is not None]
        if given:
            raise ParameterError(
                f"{', '.join(given)} given without --payload-mass: give the payload's mass in [kg]",
                name="payload_mass",
            )
        return None
    com, inertia, frame = others.values()
    return Payload(
        mass=mass,
        com=(0.0, 0.0, 0.0) if com is None else tuple(com),
        inertia=((0.0, 0.0, 0.0),) * 3 if inertia is None else tuple(inertia),
        frame=frame,
    )


def ipopt_options(args: argparse.Namespace) -> IpoptOptions:
    """Return the :class:`IpoptOptions` of ``--max-iter``, ``--hessian`` and ``--linear-solver``.

    ``--linear-solver-library`` too: the library IPOPT loads the linear solver from.
    """
    return IpoptOptions(
        max_iter=args.max_iter,
        hessian=args.hessian,
        linear_solver=args.linear_solver,
        linear_solver_library=args.linear_solver_library,
    )


def report_shard(report: ShardReport) -> int:
    """Print what a ``--shard I/K`` run did (on stderr) and return its exit status, 0.

    A shard that solved its share is a success; the message says how many of
    the sweep's items are finished and how to collect them.
    """
    print(f"youbot-opt: {report}", file=sys.stderr)
    return 0


def scheduler_address(args: argparse.Namespace) -> str | None:
    """Return the scheduler address named by the flags (``None``: neither flag given).

    A scheduler file is read for its ``address``; the sweep connects (and
    disconnects) itself, so the address is all a command passes on as
    ``SweepOptions(executor=...)``.

    Raises
    ------
    ParameterError
        If the file is missing, not a regular file, too large or names no
        address, the address is not sane (see
        :func:`~youbot_opt.sweeps.scheduler.check_scheduler_address`), or
        ``--workers 0`` / ``--item-timeout`` is combined with a scheduler.
    """
    address = getattr(args, "scheduler", None)
    path = getattr(args, "scheduler_file", None)
    if address is None and path is None:
        return None
    if getattr(args, "workers", None) == 0:
        raise ParameterError(
            "--workers 0 (in-process) cannot be combined with --scheduler/--scheduler-file",
            name="workers",
        )
    if getattr(args, "item_timeout", None) is not None:
        raise ParameterError(
            "--item-timeout needs local worker processes; it cannot be combined with "
            "--scheduler/--scheduler-file",
            name="item_timeout",
        )
    if path is not None:
        return read_scheduler_file(path, name="scheduler_file")
    if not is_scheduler_address(address):
        raise ParameterError(
            f"--scheduler must be an address such as tcp://10.0.0.5:8786, got {address!r}",
            name="scheduler",
        )
    return check_scheduler_address(address, name="scheduler")


def clearance_of(args: argparse.Namespace, robot: RobotModel | None = None) -> Clearance | None:
    """Return the problem's clearance from the ``--scene`` flags (``_clearance_arguments``).

    ``--srdf`` and ``--disable-pair`` choose the self-collision pairs of
    ``robot`` (default: the robot of ``args``). None without ``--scene`` and
    ``--margin``: the scene-less problem.
    """
    scene_file = getattr(args, "scene", None)
    margin = getattr(args, "margin", None)
    srdf = getattr(args, "srdf", None)
    disable = [tuple(pair) for pair in getattr(args, "disable_pair", None) or ()]
    end_window = getattr(args, "end_window", None)
    if scene_file is None and margin is None:
        for flag, given in (
            ("no_self_collision", getattr(args, "no_self_collision", False)),
            ("end_window", end_window is not None),
            ("srdf", srdf is not None),
            ("disable_pair", bool(disable)),
        ):
            if given:
                raise ParameterError(
                    f"--{flag.replace('_', '-')} needs --scene or --margin (without them "
                    "there is nothing to check)",
                    name=flag,
                )
        return None
    pairs = None
    if srdf is not None or disable:
        pairs = self_collision_pairs(
            load_robot(args) if robot is None else robot,
            srdf=True if srdf is None else srdf,
            disable=disable,
        )
    return Clearance(
        scene=Scene() if scene_file is None else load_scene(scene_file),
        margin=0.0 if margin is None else margin,
        self_collision=not args.no_self_collision,
        pairs=pairs,
        **({} if end_window is None else {"end_window": end_window}),
    )
