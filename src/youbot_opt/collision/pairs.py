r"""Self-collision pairs of a robot's collision geometry.

Every pair of collision geometries of different links, without the pairs of
adjacent links (the same moving body, or bodies joined by one joint), without
those an SRDF disables (``<disable_collisions>``: the SRDF given, or the one
example-robot-data ships beside the URDF) and without those the caller
disables. :func:`pairs_report` gives the lines the ``report`` command prints.

>>> pairs = self_collision_pairs(load_model("panda"))  # doctest: +SKIP
>>> print("\\n".join(pairs_report(pairs)))  # doctest: +SKIP
"""

from __future__ import annotations

import difflib
import logging
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pinocchio as pin

from youbot_opt._checks import shown
from youbot_opt.exceptions import ModelError, ParameterError
from youbot_opt.robot.model import RobotModel

__all__ = ["CollisionPairs", "find_srdf", "pairs_report", "self_collision_pairs"]

_log = logging.getLogger(__name__)
#: Largest SRDF read, in bytes (example-robot-data's are under 100 kB).
_MAX_SRDF_BYTES = 4 << 20


@dataclass(frozen=True, slots=True, kw_only=True)
class CollisionPairs:
    """The active self-collision pairs of a robot and why the others are not.

    Attributes
    ----------
    robot : str
        The robot's name.
    active : tuple of (str, str)
        Pairs of collision geometry names checked, each in model order.
    adjacent : tuple of (str, str)
        Pairs left out because their links are the same body or joined by a joint.
    srdf_disabled : tuple of (str, str)
        Pairs left out because the SRDF disables them.
    user_disabled : tuple of (str, str)
        Pairs left out because the caller disabled them.
    srdf : str or None
        The SRDF file read, or None.
    """

    robot: str
    active: tuple[tuple[str, str], ...]
    adjacent: tuple[tuple[str, str], ...] = ()
    srdf_disabled: tuple[tuple[str, str], ...] = ()
    user_disabled: tuple[tuple[str, str], ...] = ()
    srdf: str | None = None


def find_srdf(robot: RobotModel) -> Path | None:
    """Return the SRDF shipped beside the robot's URDF, or None.

    Looked for, in order: ``<stem>.srdf`` beside the URDF, then in ``../srdf/``
    (example-robot-data's layout), for the URDF's stem, the stem without a
    ``_robot`` suffix, and the robot's name.

    Parameters
    ----------
    robot : RobotModel
        The robot.

    Returns
    -------
    pathlib.Path or None
        The SRDF file.
    """
    if robot.urdf_path is None:
        return None
    urdf = Path(robot.urdf_path)
    stems = [urdf.stem, urdf.stem.removesuffix("_robot"), robot.name]
    for folder in (urdf.parent, urdf.parent.parent / "srdf"):
        for stem in stems:
            candidate = folder / f"{stem}.srdf"
            if candidate.is_file():
                return candidate
    return None


def _adjacent(model: pin.Model, joint_a: int, joint_b: int) -> bool:
    """Return True when two bodies are the same or joined by one joint."""
    return (
        joint_a == joint_b or model.parents[joint_b] == joint_a or model.parents[joint_a] == joint_b
    )


def _pair_names(geom: pin.GeometryModel) -> set[tuple[str, str]]:
    names = [g.name for g in geom.geometryObjects]
    return {(names[p.first], names[p.second]) for p in geom.collisionPairs}


def _check_disable(
    disable: Iterable[tuple[str, str]], names: list[str], links: dict[str, set[str]]
) -> set[frozenset[str]]:
    """Return the geometry pairs the caller disables (by geometry or link names), checked."""
    out: set[frozenset[str]] = set()
    for i, item in enumerate(disable):
        if isinstance(item, str) or len(item) != 2:
            raise ParameterError(
                f"disable[{i}] must be a pair of geometry or link names, got {shown(item)}",
                name=f"disable[{i}]",
                value=item,
            )
        sides = []
        for name in item:
            if name in links:
                sides.append(links[name])
            elif name in names:
                sides.append({name})
            else:
                close = difflib.get_close_matches(str(name), [*links, *names], n=5, cutoff=0.5)
                raise ParameterError(
                    f"disable[{i}]: {shown(name)} is neither a collision geometry nor a link; "
                    f"close names: {close or 'none'}; geometries: {names}, links: {sorted(links)}",
                    name=f"disable[{i}]",
                    value=name,
                )
        out |= {frozenset((a, b)) for a in sides[0] for b in sides[1] if a != b}
    return out


def self_collision_pairs(
    robot: RobotModel,
    *,
    srdf: str | os.PathLike[str] | bool = True,
    disable: Iterable[tuple[str, str]] = (),
) -> CollisionPairs:
    """Return the robot's self-collision pairs.

    Parameters
    ----------
    robot : RobotModel
        The robot, with its collision geometry from the loader.
    srdf : path-like or bool
        An SRDF file to read; True (default): the SRDF shipped beside the URDF
        when there is one (:func:`find_srdf`); False: none.
    disable : iterable of (str, str)
        More pairs to leave out, each two geometry names or link names (a
        link name stands for all its geometries).

    Returns
    -------
    CollisionPairs
        The active pairs and the left-out ones with the reason.

    Raises
    ------
    ParameterError
        ``disable`` names an unknown geometry or link, or ``srdf`` is not a file.
    ModelError
        Pinocchio cannot read the SRDF.
    """
    model, collision = robot.model, robot.collision_model
    geoms = list(collision.geometryObjects)
    names = [g.name for g in geoms]
    links: dict[str, set[str]] = {}
    for g in geoms:
        links.setdefault(model.frames[g.parentFrame].name, set()).add(g.name)
    user = _check_disable(disable, names, links)
    all_pairs, adjacent = [], []
    for a in range(len(geoms)):
        for b in range(a + 1, len(geoms)):
            pair = (names[a], names[b])
            if _adjacent(model, geoms[a].parentJoint, geoms[b].parentJoint):
                adjacent.append(pair)
            else:
                all_pairs.append(pair)
    srdf_path: Path | None
    if srdf is True:
        srdf_path = find_srdf(robot)
    elif srdf is False:
        srdf_path = None
    else:
        srdf_path = Path(srdf)  # type: ignore[arg-type]
        if not srdf_path.is_file():
            raise ParameterError(f"srdf {shown(str(srdf))} is not a file", name="srdf", value=srdf)
    srdf_off: set[tuple[str, str]] = set()
    if srdf_path is not None:
        if srdf_path.stat().st_size > _MAX_SRDF_BYTES:
            raise ParameterError(
                f"srdf {str(srdf_path)!r} is larger than {_MAX_SRDF_BYTES} bytes",
                name="srdf",
                value=str(srdf_path),
            )
        work = pin.GeometryModel(collision)
        work.addAllCollisionPairs()
        before = _pair_names(work)
        try:
            pin.removeCollisionPairs(model, work, str(srdf_path))
        except (RuntimeError, ValueError) as e:
            raise ModelError(
                f"cannot read the SRDF {str(srdf_path)!r}: {e}", path=str(srdf_path)
            ) from e
        srdf_off = before - _pair_names(work)
        _log.debug("SRDF %s disables %d pairs", srdf_path, len(srdf_off))
    active, srdf_disabled, user_disabled = [], [], []
    for pair in all_pairs:
        if pair in srdf_off:
            srdf_disabled.append(pair)
        elif frozenset(pair) in user:
            user_disabled.append(pair)
        else:
            active.append(pair)
    return CollisionPairs(
        robot=robot.name,
        active=tuple(active),
        adjacent=tuple(adjacent),
        srdf_disabled=tuple(srdf_disabled),
        user_disabled=tuple(user_disabled),
        srdf=None if srdf_path is None else str(srdf_path),
    )


def pairs_report(pairs: CollisionPairs) -> list[str]:
    """Return the lines the ``report`` command prints about self-collision.

    Parameters
    ----------
    pairs : CollisionPairs
        From :func:`self_collision_pairs`.

    Returns
    -------
    list of str
        A summary line (counts and SRDF), then one line per active pair, then
        one per left-out pair with the reason (adjacent, SRDF or user).
    """
    lines = [
        f"self-collision: {len(pairs.active)} active pairs ({len(pairs.adjacent)} adjacent, "
        f"{len(pairs.srdf_disabled)} disabled by SRDF {pairs.srdf or '-'}, "
        f"{len(pairs.user_disabled)} disabled by the caller)"
    ]
    lines += [f"  {a} <-> {b}" for a, b in pairs.active]
    for reason, left_out in (
        ("adjacent", pairs.adjacent),
        ("SRDF", pairs.srdf_disabled),
        ("user", pairs.user_disabled),
    ):
        lines += [f"  {a} <-> {b}  disabled ({reason})" for a, b in left_out]
    return lines
