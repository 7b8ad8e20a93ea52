"""Size limits of a URDF's kinematic tree, checked before any expensive step (issue 16).

:func:`check_urdf_size` refuses a parsed file with more joints, a longer chain
of joints or more degrees of freedom than :data:`MAX_JOINTS`,
:data:`MAX_TREE_DEPTH` and :data:`MAX_DOF`, before the tree rules and before
Pinocchio's parser. :class:`SizeLimits` gathers these and the XML limits of
:mod:`youbot_opt.robot.urdf_check.xml` for one call; the environment variables
``YOUBOT_OPT_<NAME>`` (e.g. ``YOUBOT_OPT_MAX_JOINTS``) set the defaults. Why
each limit is where it is: docs/design.md, "Module notes".

Example: ``load_model(path, size_limits=SizeLimits(max_joints=5000))``, or
``YOUBOT_OPT_MAX_JOINTS=5000 youbot-opt robots big.urdf``.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass, fields

from lxml import etree

from youbot_opt.exceptions import ParameterError, UnsafeURDFError
from youbot_opt.robot.urdf_check.xml import (
    MAX_XML_DEPTH,
    MAX_XML_ELEMENTS,
    Site,
    fail,
    limit,
    root_of,
)

__all__ = [
    "MAX_DOF",
    "MAX_JOINTS",
    "MAX_TREE_DEPTH",
    "SizeLimits",
    "check_urdf_size",
    "tree_depth",
]

#: Most ``<joint>`` elements accepted (fixed ones included). Large humanoids
#: and multi-arm cells have a few hundred; Pinocchio's model data grows with
#: the square of the joint count in places (M(q) is nv x nv).
#: Environment variable: ``YOUBOT_OPT_MAX_JOINTS``.
MAX_JOINTS: int = 1000
#: Most degrees of freedom (velocity coordinates of the movable joints:
#: revolute, continuous and prismatic 1, planar 3, floating 6). Pinocchio's
#: ``Data`` grows faster than the square of ``nv``: measured 0.6 GB resident
#: for a 250-joint chain and 4.1 GB for 500 (Pinocchio 4.1); the loader's checks
#: of a 100-joint chain take about a second. Real arms, hands and humanoids
#: have fewer than 100.
#: Environment variable: ``YOUBOT_OPT_MAX_DOF``.
MAX_DOF: int = 100
#: Nominal velocity coordinates of each joint type.
_NV = {"revolute": 1, "continuous": 1, "prismatic": 1, "planar": 3, "floating": 6}
#: Longest chain of joints from the root link to a leaf. Pinocchio's URDF
#: parser recurses once per level (~1.6 kB of C stack each; it overflows an
#: 8 MiB stack near 5,000 levels); 500 keeps a margin of ten.
#: Environment variable: ``YOUBOT_OPT_MAX_TREE_DEPTH``.
MAX_TREE_DEPTH: int = 500


@dataclass(frozen=True, slots=True, kw_only=True)
class SizeLimits:
    """Size limits of a URDF file, for one call of the strict loader.

    Every limit is a count (an integer >= 1); ``None`` (the default) takes the
    environment variable ``YOUBOT_OPT_<NAME>`` (e.g. ``YOUBOT_OPT_MAX_JOINTS``)
    when it is set, else the module constant.

    Attributes
    ----------
    max_joints : int or None
        Most ``<joint>`` elements, fixed ones included [count];
        :data:`MAX_JOINTS` = 1000, ``YOUBOT_OPT_MAX_JOINTS``.
    max_dof : int or None
        Most degrees of freedom (velocity coordinates of the movable joints)
        [count]; :data:`MAX_DOF` = 100, ``YOUBOT_OPT_MAX_DOF``.
    max_tree_depth : int or None
        Longest chain of joints from the root link [count of joints];
        :data:`MAX_TREE_DEPTH` = 500, ``YOUBOT_OPT_MAX_TREE_DEPTH``.
    max_xml_depth : int or None
        Deepest XML element nesting [levels, ``<robot>`` is 1];
        :data:`~youbot_opt.robot.urdf_check.xml.MAX_XML_DEPTH` = 100,
        ``YOUBOT_OPT_MAX_XML_DEPTH``.
    max_xml_elements : int or None
        Most XML elements in the file [count];
        :data:`~youbot_opt.robot.urdf_check.xml.MAX_XML_ELEMENTS` = 200,000,
        ``YOUBOT_OPT_MAX_XML_ELEMENTS``.

    Raises
    ------
    ParameterError
        If a limit is not None or an integer >= 1 (the message names it).
    """

    max_joints: int | None = None
    max_dof: int | None = None
    max_tree_depth: int | None = None
    max_xml_depth: int | None = None
    max_xml_elements: int | None = None

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if value is None:
                continue
            try:
                count = operator.index(value) if not isinstance(value, bool) else 0
            except TypeError:
                count = 0
            if count < 1:
                raise ParameterError(
                    f"size limit {item.name} must be an integer >= 1 (a count) or None "
                    f"(the default), got {value!r}",
                    name=item.name,
                    value=value,
                )
            object.__setattr__(self, item.name, count)

    def resolved(self) -> SizeLimits:
        """Return the limits in effect: each value given, else its environment variable or default.

        Raises
        ------
        ParameterError
            If an environment variable that is used is not an integer >= 1.
        """
        return SizeLimits(
            max_joints=limit("MAX_JOINTS", MAX_JOINTS, self.max_joints),
            max_dof=limit("MAX_DOF", MAX_DOF, self.max_dof),
            max_tree_depth=limit("MAX_TREE_DEPTH", MAX_TREE_DEPTH, self.max_tree_depth),
            max_xml_depth=limit("MAX_XML_DEPTH", MAX_XML_DEPTH, self.max_xml_depth),
            max_xml_elements=limit("MAX_XML_ELEMENTS", MAX_XML_ELEMENTS, self.max_xml_elements),
        )


def tree_depth(robot: etree._Element) -> int:
    """Return the longest chain of joints from a root link, without recursion.

    Parameters
    ----------
    robot : Element
        The ``<robot>`` element, not yet checked: joints without a parent or
        child, unknown links and loops are tolerated (the tree rules report them).

    Returns
    -------
    int
        Number of joints on the longest path from a link without a parent
        joint (0 for a robot without joints; loops count once around).
    """
    parent_of: dict[str, str] = {}
    for joint in robot.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is not None and child is not None:
            parent_of.setdefault(child.get("link", ""), parent.get("link", ""))
    depth: dict[str, int] = {}
    for start in parent_of:
        chain, link, seen = [], start, set()
        while link in parent_of and link not in depth and link not in seen:
            seen.add(link)
            chain.append(link)
            link = parent_of[link]
        base = depth.get(link, 0)
        for offset, name in enumerate(reversed(chain), start=1):
            depth[name] = base + offset
    return max(depth.values(), default=0)


def check_urdf_size(
    tree: etree._ElementTree,
    path: str,
    *,
    max_joints: int | None = None,
    max_depth: int | None = None,
    max_dof: int | None = None,
) -> None:
    """Refuse a URDF with too many joints or too deep a tree, before anything costly.

    Parameters
    ----------
    tree : lxml.etree._ElementTree
        The parsed file (:func:`~youbot_opt.robot.urdf_check.xml.parse_xml_strict`).
    path : str
        Its file, for error messages.
    max_joints : int, optional
        Most joints; default :data:`MAX_JOINTS` or ``YOUBOT_OPT_MAX_JOINTS``.
    max_depth : int, optional
        Longest joint chain; default :data:`MAX_TREE_DEPTH` or
        ``YOUBOT_OPT_MAX_TREE_DEPTH``.
    max_dof : int, optional
        Most degrees of freedom; default :data:`MAX_DOF` or ``YOUBOT_OPT_MAX_DOF``.

    Raises
    ------
    UnsafeURDFError
        Naming the count, the limit and how to raise it.
    ParameterError
        If a limit (argument or environment variable) is not an integer >= 1.
    """
    joints_limit = limit("MAX_JOINTS", MAX_JOINTS, max_joints)
    depth_limit = limit("MAX_TREE_DEPTH", MAX_TREE_DEPTH, max_depth)
    dof_limit = limit("MAX_DOF", MAX_DOF, max_dof)
    robot = root_of(tree, path)
    where = Site(path, f"<{robot.tag}>", getattr(robot, "sourceline", None))
    rule = (
        f"at most {joints_limit:,} joints, {dof_limit:,} degrees of freedom and chains "
        f"of at most {depth_limit:,} joints"
    )
    joints = robot.findall("joint")
    if len(joints) > joints_limit:
        problem = (
            f"has {len(joints):,} joints, more than the limit of {joints_limit:,} (raise it with "
            "size_limits=SizeLimits(max_joints=...) or the environment variable "
            "YOUBOT_OPT_MAX_JOINTS)"
        )
        raise fail(UnsafeURDFError, where, problem, rule)
    dof = sum(_NV.get(j.get("type", ""), 0) for j in joints)
    if dof > dof_limit:
        problem = (
            f"has {dof:,} degrees of freedom, more than the limit of {dof_limit:,} "
            "(Pinocchio's data grows faster than dof^2: 0.6 GB at 250, 4 GB at 500; raise it "
            "with size_limits=SizeLimits(max_dof=...) or the environment variable "
            "YOUBOT_OPT_MAX_DOF)"
        )
        raise fail(UnsafeURDFError, where, problem, rule)
    depth = tree_depth(robot)
    if depth > depth_limit:
        problem = (
            f"has a chain of {depth:,} joints, deeper than the limit of {depth_limit:,} "
            "(raise it with size_limits=SizeLimits(max_tree_depth=...) or the environment "
            "variable YOUBOT_OPT_MAX_TREE_DEPTH)"
        )
        raise fail(UnsafeURDFError, where, problem, rule)
