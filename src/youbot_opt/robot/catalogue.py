"""The robots known by name: the committed youBot files and the installed example-robot-data.

:func:`available_robots` lists the names :func:`~youbot_opt.robot.load.load_model`
accepts; :func:`find_robot` turns a name into its URDF file and default tip frame.
Every robot of example-robot-data is found in its installed ``robots`` folder
(:func:`example_robots`), not from a list kept here; a few short names (``ur5``,
``panda``) carry their tip frames.

>>> available_robots()[:3]  # doctest: +SKIP
('youbot', 'youbot_arm_5dof', 'double_pendulum')
"""

from __future__ import annotations

import functools
import importlib.metadata
from pathlib import Path
from typing import NamedTuple

from youbot_opt.exceptions import ModelError
from youbot_opt.robot.urdf import TIP_FRAME

__all__ = [
    "YOUBOT",
    "YOUBOT_ARM_5DOF",
    "CatalogueEntry",
    "available_robots",
    "example_package_dirs",
    "example_robot_data_dir",
    "example_robots",
    "find_robot",
    "youbot_urdf_path",
]

YOUBOT = "youbot"
_YOUBOT_FILE = "youbot_arm_planar.urdf"
YOUBOT_ARM_5DOF = "youbot_arm_5dof"
_YOUBOT_5DOF_FILE = "youbot_arm_5dof.urdf"
_YOUBOT_5DOF_TIP = "gripper_palm_link"

# Short names kept from before the whole zoo loaded by name, and their tip frames:
# name -> (URDF path relative to example-robot-data's ``robots`` folder, default tip frame).
# Every other robot of example-robot-data is found in its folder (example_robots()).
_EXAMPLE_ROBOTS: dict[str, tuple[str, str]] = {
    "double_pendulum": ("double_pendulum_description/urdf/double_pendulum.urdf", "link2"),
    "ur3": ("ur_description/urdf/ur3_robot.urdf", "tool0"),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand_tcp"),
    "so101": ("so_arm_description/urdf/so101.urdf", "gripper_frame_link"),
    "z1": ("z1_description/urdf/z1.urdf", "gripperStator"),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "link_eef"),
}


class CatalogueEntry(NamedTuple):
    """Where a robot known by name lives.

    Attributes
    ----------
    urdf_path : pathlib.Path
        Its URDF file.
    tip_frame : str or None
        Its default end-effector frame; None: the model's last frame.
    """

    urdf_path: Path
    tip_frame: str | None


def youbot_urdf_path() -> Path:
    """Return the committed youBot URDF (source checkout, else the packaged copy).

    Returns
    -------
    pathlib.Path
        ``<repo>/urdf/youbot_arm_planar.urdf`` if it exists, else
        ``youbot_opt/_urdf/youbot_arm_planar.urdf``.
    """
    return _committed_urdf(_YOUBOT_FILE)


def _committed_urdf(filename: str) -> Path:
    """Return ``urdf/<filename>`` of the source checkout, else the packaged copy."""
    repo = Path(__file__).resolve().parents[3] / "urdf" / filename
    if repo.is_file():
        return repo
    return Path(__file__).resolve().parents[1] / "_urdf" / filename


def example_robot_data_dir() -> Path:
    """Return example-robot-data's ``share`` folder (holds ``example-robot-data/robots``).

    Returns
    -------
    pathlib.Path
        The folder that ``package://example-robot-data/...`` references resolve against.

    Raises
    ------
    ModelError
        If example-robot-data is not installed (``pip install example-robot-data``).
    """
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError as exc:
        raise ModelError(
            "example-robot-data is not installed; run `pip install example-robot-data`"
        ) from exc
    for f in dist.files or ():
        parts = f.parts
        for k in range(len(parts) - 1):
            if parts[k] == "example-robot-data" and parts[k + 1] == "robots":
                return Path(str(dist.locate_file(Path(*parts[:k]))))
    raise ModelError("example-robot-data is installed but ships no robots/ folder")


def _robots_folder() -> Path:
    return example_robot_data_dir() / "example-robot-data" / "robots"


@functools.cache
def _example_robots_cached(robots: Path) -> tuple[tuple[str, str], ...]:
    files = sorted(p.relative_to(robots).as_posix() for p in robots.rglob("*.urdf"))
    stems: dict[str, list[str]] = {}
    for rel in files:
        stems.setdefault(Path(rel).stem, []).append(rel)
    names = []
    for rel in files:
        stem = Path(rel).stem
        alias = _EXAMPLE_ROBOTS.get(stem)
        unique = len(stems[stem]) == 1 and (alias is None or alias[0] == rel)
        names.append((stem if unique else f"{Path(rel).parts[0]}/{stem}", rel))
    return tuple(names)


def example_robots() -> dict[str, Path]:
    """Return every robot of the installed example-robot-data: name -> URDF file.

    Found from the installed data (each ``*.urdf`` under its ``robots``
    folder), not from a list kept here. A robot is named by its file name
    without ``.urdf`` (``panda``, ``ur5_robot``, ``talos_left_arm``); a name
    shared by several files, or taken by a short name below, is qualified by
    its package folder (``anymal_b_simple_description/anymal``,
    ``ur_description/ur3``). The short names ``ur3``, ``ur5`` and ``ur10``
    (``ur*_robot``) are accepted by :func:`~youbot_opt.robot.load.load_model` besides these.

    Returns
    -------
    dict of str to pathlib.Path
        One entry per URDF file, sorted by path.

    Raises
    ------
    ModelError
        If example-robot-data is not installed.
    """
    robots = _robots_folder()
    return {name: robots / rel for name, rel in _example_robots_cached(robots)}


def available_robots() -> tuple[str, ...]:
    """Return the robot names :func:`~youbot_opt.robot.load.load_model` accepts.

    Returns
    -------
    tuple of str
        ``"youbot"``, ``"youbot_arm_5dof"``, the short example-robot-data names
        (``ur5``, ``panda``, ...), then every other robot of the installed
        example-robot-data (:func:`example_robots`; none when it is not installed).
    """
    try:
        zoo = tuple(example_robots())
    except ModelError:
        zoo = ()
    return tuple(dict.fromkeys((YOUBOT, YOUBOT_ARM_5DOF, *_EXAMPLE_ROBOTS, *zoo)))


def find_robot(name: str) -> CatalogueEntry | None:
    """Return the URDF file and default tip frame of a robot known by name.

    Parameters
    ----------
    name : str
        ``"youbot"``, ``"youbot_arm_5dof"`` or a name of the installed
        example-robot-data (:func:`available_robots`).

    Returns
    -------
    CatalogueEntry or None
        The file and tip frame; None for a name not known (or when
        example-robot-data is not installed and the name is one of its).
    """
    if name == YOUBOT:
        return CatalogueEntry(_committed_urdf(_YOUBOT_FILE), TIP_FRAME)
    if name == YOUBOT_ARM_5DOF:
        return CatalogueEntry(_committed_urdf(_YOUBOT_5DOF_FILE), _YOUBOT_5DOF_TIP)
    if name in _EXAMPLE_ROBOTS:
        rel, tip = _EXAMPLE_ROBOTS[name]
        return CatalogueEntry(_robots_folder() / rel, tip)
    try:
        zoo = example_robots()
    except ModelError:
        return None
    return CatalogueEntry(zoo[name], None) if name in zoo else None


def example_package_dirs(path: Path) -> tuple[Path, ...]:
    """Return the package folders of example-robot-data if ``path`` lies in it.

    Parameters
    ----------
    path : pathlib.Path
        A URDF file.

    Returns
    -------
    tuple of pathlib.Path
        Its ``robots`` and ``share`` folders, against which ``package://``
        references resolve; empty when ``path`` is not in it (or it is not installed).
    """
    try:
        share = example_robot_data_dir()
    except ModelError:
        return ()
    robots = share / "example-robot-data" / "robots"
    real = path.resolve()
    if real.is_relative_to(robots.resolve()):
        return (robots, share)
    return ()
