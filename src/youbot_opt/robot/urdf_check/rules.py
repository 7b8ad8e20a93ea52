"""Structural and physical rules a parsed URDF must pass (issue 6, item 1).

:func:`check_urdf_tree` checks a tree from :func:`youbot_opt.robot.urdf_check.xml.parse_xml_strict`
(the rules are listed there); the first broken rule raises, naming file, element,
line and rule. :func:`implausible_inertias` and :func:`welded_links` report the
inertias the loader warns about or refuses; :func:`check_mimic_graph` the mimic
relations; :func:`file_inertia` and :func:`file_limits` read what a checked file
says in the form Pinocchio holds it. Mesh and texture references are checked by
:mod:`youbot_opt.robot.urdf_check.resources`. The plausibility rule is explained in
docs/design.md, "Module notes".
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import numpy as np
from lxml import etree

from youbot_opt.exceptions import InvalidModelError, URDFStructureError
from youbot_opt.robot.urdf_check.xml import (
    NUMBER_RULE,
    Site,
    fail,
    parse_number,
    root_of,
    shorten,
    site,
)

__all__ = [
    "JOINT_TYPES",
    "FileLimits",
    "InertiaFinding",
    "check_mimic_graph",
    "check_urdf_tree",
    "file_inertia",
    "file_limits",
    "implausible_inertias",
    "resource_references",
    "welded_links",
]

#: Joint types of the URDF specification (all supported by Pinocchio).
JOINT_TYPES: tuple[str, ...] = (
    "revolute",
    "continuous",
    "prismatic",
    "fixed",
    "floating",
    "planar",
)
_WITH_AXIS = ("revolute", "continuous", "prismatic", "planar")
_SIZES = {
    "box": (("size", 3),),
    "cylinder": (("radius", 1), ("length", 1)),
    "sphere": (("radius", 1),),
}
_SHAPES = (*_SIZES, "mesh")
_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
#: Relative tolerance (of the trace) of the inertia rules: URDF exporters print
#: about 6-7 significant digits, so a body exactly on the boundary (a flat
#: plate has I1 + I2 = I3) may miss it by ~1e-6 of the trace after rounding.
_INERTIA_RTOL = 1e-6
#: Absolute tolerance of the inertia rules in [kg m^2], for round-off such as
#: 1e-35 off-diagonal terms: far below any real part (1 g at 1 mm: 1e-9 kg m^2).
_INERTIA_ATOL = 1e-12
#: Units of (position, velocity, effort) limits by URDF joint type.
_LIMIT_UNITS = {
    "revolute": ("rad", "rad/s", "N m"),
    "continuous": ("rad", "rad/s", "N m"),
    "prismatic": ("m", "m/s", "N"),
}
_TREE_RULE = "the links form one tree (one root, one parent joint per link, no loops)"
_OPTIONAL_NUMBERS = (  # (element, attributes, must be >= 0) of <joint>
    ("dynamics", ("damping", "friction"), True),
    (
        "safety_controller",
        ("soft_lower_limit", "soft_upper_limit", "k_position", "k_velocity"),
        False,
    ),
    ("calibration", ("rising", "falling", "reference_position"), False),
    ("mimic", ("multiplier", "offset"), False),
)


def _invalid(where: Site, problem: str, rule: str) -> InvalidModelError:
    return fail(InvalidModelError, where, problem, rule)  # type: ignore[return-value]


def _broken(where: Site, problem: str, rule: str) -> URDFStructureError:
    return fail(URDFStructureError, where, problem, rule)  # type: ignore[return-value]


def _numbers(
    elem: etree._Element, attr: str, count: int, where: Site, default: str | None = None
) -> tuple[float, ...]:
    text = elem.get(attr, default)
    if text is None:
        raise _broken(where, f"attribute {attr!r} is missing", f"<{elem.tag}> has {attr!r}")
    parts = text.split()
    if len(parts) != count:
        problem = f"{attr}={shorten(text)} has {len(parts)} numbers, not {count}"
        raise _invalid(where, problem, NUMBER_RULE)
    return tuple(parse_number(p, where, attr) for p in parts)


def _one(parent: etree._Element, tag: str, where: Site, *, required: bool) -> etree._Element | None:
    found = parent.findall(tag)
    if len(found) > 1 or (required and not found):
        rule = f"{'exactly' if required else 'at most'} one <{tag}>"
        raise _broken(where, f"has {len(found)} <{tag}> elements", rule)
    return found[0] if found else None


def _check_origin(parent: etree._Element, path: str, owner: str) -> None:
    origin = _one(parent, "origin", site(path, parent, owner), required=False)
    if origin is not None:
        for attr in ("xyz", "rpy"):
            _numbers(origin, attr, 3, site(path, origin, owner), default="0 0 0")


def _check_inertial(inertial: etree._Element, path: str, owner: str) -> None:
    where = site(path, inertial, owner)
    _check_origin(inertial, path, owner)
    mass_elem = _one(inertial, "mass", where, required=True)
    inertia_elem = _one(inertial, "inertia", where, required=True)
    assert mass_elem is not None and inertia_elem is not None
    (mass,) = _numbers(mass_elem, "value", 1, site(path, mass_elem, owner))
    if mass < 0:
        raise _invalid(site(path, mass_elem, owner), f"mass {mass} kg is negative", "mass >= 0")
    iw = site(path, inertia_elem, owner)
    ixx, ixy, ixz, iyy, iyz, izz = (_numbers(inertia_elem, k, 1, iw)[0] for k in _INERTIA_KEYS)
    del ixx, ixy, ixz, iyy, iyz, izz  # read to check the numbers; plausibility: below


def _check_geometry(parent: etree._Element, path: str, owner: str) -> None:
    _check_origin(parent, path, owner)
    geometry = _one(parent, "geometry", site(path, parent, owner), required=True)
    assert geometry is not None
    shapes = list(geometry)
    if len(shapes) != 1 or shapes[0].tag not in _SHAPES:
        rule = f"<geometry> holds exactly one of {', '.join(_SHAPES)}"
        raise _broken(site(path, geometry, owner), f"holds {[s.tag for s in shapes]}", rule)
    shape = shapes[0]
    where = site(path, shape, owner)
    for attr, count in _SIZES.get(shape.tag, ()):
        if min(_numbers(shape, attr, count, where)) <= 0:
            raise _invalid(where, f"{attr}={shape.get(attr)!r} is not positive", "sizes > 0 m")
    if shape.tag == "mesh":
        if not shape.get("filename", "").strip():
            raise _broken(where, "filename is missing", "a mesh names its file")
        if 0.0 in _numbers(shape, "scale", 3, where, default="1 1 1"):
            raise _invalid(where, "scale has a zero component", "mesh scale is non-zero")
    material = parent.find("material")
    if material is not None:
        _check_material(material, path, owner)


def _check_material(material: etree._Element, path: str, owner: str) -> None:
    color = material.find("color")
    if color is not None:
        _numbers(color, "rgba", 4, site(path, color, owner))


def _check_link(link: etree._Element, path: str) -> None:
    owner = f"link {link.get('name')!r}"
    inertial = _one(link, "inertial", site(path, link), required=False)
    if inertial is not None:
        _check_inertial(inertial, path, owner)
    for part in link.findall("visual") + link.findall("collision"):
        _check_geometry(part, path, owner)


def _check_limit(limit: etree._Element, jtype: str, where: Site) -> None:
    lower, upper = (_numbers(limit, k, 1, where, default="0")[0] for k in ("lower", "upper"))
    effort, velocity = (_numbers(limit, k, 1, where)[0] for k in ("effort", "velocity"))
    if jtype != "continuous" and lower > upper:
        raise _invalid(where, f"lower={lower} > upper={upper}", "lower <= upper")
    if effort < 0 or velocity < 0:
        problem = f"effort={effort} or velocity={velocity} is negative"
        raise _invalid(where, problem, "effort >= 0 and velocity >= 0")


def _check_joint(joint: etree._Element, path: str, links: set[str], joints: set[str]) -> None:
    jtype, owner, where = joint.get("type", ""), f"joint {joint.get('name')!r}", site(path, joint)
    if jtype not in JOINT_TYPES:
        raise _broken(
            where, f"type={jtype!r} is unknown", f"type is one of {', '.join(JOINT_TYPES)}"
        )
    for tag in ("parent", "child"):
        elem = _one(joint, tag, where, required=True)
        assert elem is not None
        if elem.get("link") not in links:
            problem = f"<{tag} link={elem.get('link')!r}> names no link of the robot"
            raise _broken(site(path, elem, owner), problem, "parent and child are defined links")
    _check_origin(joint, path, owner)
    axis = _one(joint, "axis", where, required=False)
    if axis is not None and jtype in _WITH_AXIS:
        if not any(_numbers(axis, "xyz", 3, site(path, axis, owner))):
            raise _invalid(
                site(path, axis, owner), "axis is zero", "a movable joint's axis is non-zero"
            )
    limit = _one(joint, "limit", where, required=jtype in ("revolute", "prismatic"))
    if limit is not None:
        _check_limit(limit, jtype, site(path, limit, owner))
    for tag, attrs, non_negative in _OPTIONAL_NUMBERS:
        elem = _one(joint, tag, where, required=False)
        if elem is None:
            continue
        ew = site(path, elem, owner)
        for attr in (a for a in attrs if elem.get(a) is not None):
            (value,) = _numbers(elem, attr, 1, ew)
            if non_negative and value < 0:
                raise _invalid(ew, f"{attr}={value} is negative", f"{attr} >= 0")
    mimic = joint.find("mimic")
    if mimic is not None and mimic.get("joint") not in joints - {joint.get("name")}:
        problem = f"mimics {mimic.get('joint')!r}"
        raise _broken(site(path, mimic, owner), problem, "a joint mimics another defined joint")


def _named(robot: etree._Element, tag: str, path: str) -> dict[str, etree._Element]:
    named: dict[str, etree._Element] = {}
    for elem in robot.findall(tag):
        name = elem.get("name", "")
        if not name.strip():
            raise _broken(site(path, elem), "has no name", f"every <{tag}> has a unique name")
        if name in named:
            problem = (
                f"name {name!r} is also used on line {getattr(named[name], 'sourceline', '?')}"
            )
            raise _broken(site(path, elem), problem, f"every <{tag}> has a unique name")
        named[name] = elem
    return named


def _check_tree(
    links: dict[str, etree._Element], joints: dict[str, etree._Element], path: str
) -> None:
    parent_joint: dict[str, etree._Element] = {}
    children: dict[str, list[str]] = {name: [] for name in links}
    for joint in joints.values():
        parent = joint.find("parent").get("link", "")  # type: ignore[union-attr]
        child = joint.find("child").get("link", "")  # type: ignore[union-attr]
        if parent == child or child in parent_joint:
            other = (
                "itself" if parent == child else f"joint {parent_joint[child].get('name')!r} too"
            )
            problem = f"makes link {child!r} a child of {other}: a kinematic loop"
            raise _broken(site(path, joint), problem, _TREE_RULE)
        parent_joint[child] = joint
        children[parent].append(child)
    roots = [name for name in links if name not in parent_joint]
    robot_site = Site(path, "<robot>", None)
    if len(roots) != 1:
        problem = (
            f"has root links {roots}" if roots else "has no root link (the joints form a loop)"
        )
        raise _broken(robot_site, problem, _TREE_RULE)
    reached, stack = set(roots), list(roots)
    while stack:
        new = children[stack.pop()]
        reached.update(new)
        stack.extend(new)
    if len(reached) != len(links):
        loop = sorted(set(links) - reached)
        raise _broken(robot_site, f"links {loop} form a loop apart from {roots[0]!r}", _TREE_RULE)


def check_urdf_tree(tree: etree._ElementTree, path: str) -> None:
    """Check a parsed URDF against the structural and physical rules.

    Structure: a ``<robot name=...>`` root, at least one link, unique link and
    joint names, known joint types, parent and child links that exist, one root
    link and no loops, the elements URDF parsers require (``<mass>`` and
    ``<inertia>`` in an ``<inertial>``, a ``<limit>`` on revolute and prismatic
    joints, one shape in a ``<geometry>``), numbers that are finite decimals,
    and mimic relations that follow a movable joint directly
    (:func:`check_mimic_graph`: no chain or cycle).

    Physics (``m`` mass): ``m >= 0``; movable joints have a non-zero axis; a
    ``<limit>`` has ``lower <= upper``, ``velocity >= 0`` and ``effort >= 0``;
    damping and friction are ``>= 0``; box, cylinder and sphere sizes are
    ``> 0``; mesh scales are non-zero. Inertia plausibility is not checked here
    but reported by :func:`implausible_inertias` (the loader warns or refuses),
    and whether the dynamics are defined is checked on the loaded model
    (:func:`youbot_opt.robot.urdf_check.loader.check_model`).

    Parameters
    ----------
    tree : lxml.etree._ElementTree
        A tree from :func:`youbot_opt.robot.urdf_check.xml.parse_xml_strict`.
    path : str
        Its file, for error messages.

    Raises
    ------
    URDFStructureError
        Root not ``<robot name=...>``, no link, missing or duplicated names,
        unknown joint types, undefined parent/child links, several root links,
        loops, missing required elements or attributes.
    InvalidModelError
        Malformed or non-finite numbers, and values that break the physical
        rules above.
    """
    robot = root_of(tree, path)
    if robot.tag != "robot" or not robot.get("name", "").strip():
        problem = f"root element is <{robot.tag}> named {robot.get('name')!r}"
        raise _broken(site(path, robot), problem, "the root element is <robot name=...>")
    links, joints = _named(robot, "link", path), _named(robot, "joint", path)
    if not links:
        raise _broken(site(path, robot), "has no <link>", "a robot has at least one link")
    for link in links.values():
        _check_link(link, path)
    for joint in joints.values():
        _check_joint(joint, path, set(links), set(joints))
    for material in robot.findall("material"):
        _check_material(material, path, "robot")
    _check_tree(links, joints, path)
    check_mimic_graph(joints, path)


def _owner(elem: etree._Element) -> str:
    """Describe a direct child of ``<robot>``: ``link 'arm'``, ``<gazebo reference='arm'>``."""
    if elem.tag in ("link", "joint"):
        return f"{elem.tag} {elem.get('name')!r}"
    keys = [k for k in ("name", "reference") if elem.get(k) is not None]
    return "<" + " ".join([elem.tag, *(f"{k}={elem.get(k)!r}" for k in keys)]) + ">"


def _reference_site(path: str, chain: list[etree._Element]) -> Site:
    """Site of the last element of ``chain`` (from a child of ``<robot>`` down to it)."""
    *outer, elem = chain
    owner = _owner(outer[0]) if outer else "robot"
    inner = "".join(
        f"<{e.tag} name={e.get('name')!r}>" if e.get("name") else f"<{e.tag}>" for e in outer[1:]
    )
    text = f"{inner}<{elem.tag} filename={elem.get('filename')!r}> of {owner}"
    return Site(path, text, getattr(elem, "sourceline", None))


def resource_references(
    tree: etree._ElementTree, path: str
) -> Iterator[tuple[etree._Element, str, Site]]:
    """Yield every file reference of a URDF: ``<mesh filename>`` and ``<texture filename>``.

    Parameters
    ----------
    tree : lxml.etree._ElementTree
        A parsed URDF.
    path : str
        Its file, for error messages.

    Yields
    ------
    tuple of (Element, str, Site)
        The element, its kind (``"mesh"`` or ``"texture"``) and where it is,
        for error messages: its line and the chain of elements from its link
        (or other top-level element) down to it, e.g.
        ``<visual><geometry><mesh filename='package://p/m.dae'> of link 'arm'``.
        The reference is its ``filename`` attribute. References anywhere in
        the file count, also in elements the URDF parsers ignore (e.g. ``<gazebo>``).
    """
    stack: list[tuple[etree._Element, list[etree._Element]]] = [
        (child, [child]) for child in reversed(root_of(tree, path))
    ]
    while stack:  # depth first, in document order
        elem, chain = stack.pop()
        if elem.tag in ("mesh", "texture") and elem.get("filename") is not None:
            yield elem, elem.tag, _reference_site(path, chain)
        stack.extend((child, [*chain, child]) for child in reversed(elem))


class FileLimits(NamedTuple):
    """The limits a URDF gives one movable joint, as Pinocchio should hold them.

    Attributes
    ----------
    position : tuple of float or None
        ``(lower, upper)`` in [rad] or [m] for revolute and prismatic joints;
        None for the others (a continuous joint's configuration is
        ``(cos, sin)``, whose bounds are Pinocchio's own).
    velocity : ndarray, shape (nv,)
        Symmetric bound on ``|v|`` per velocity coordinate, in [rad/s] or
        [m/s]; ``inf`` where the file gives none.
    effort : ndarray, shape (nv,)
        Bound on ``|tau|`` in [N m] or [N]; ``inf`` where the file gives none.
    units : tuple of str
        Units of position, velocity and effort (empty for floating and planar).
    """

    position: tuple[float, float] | None
    velocity: np.ndarray
    effort: np.ndarray
    units: tuple[str, str, str]


def file_limits(joint: etree._Element, nv: int, where: Site) -> FileLimits:
    """Read a checked joint's ``<limit>``.

    Parameters
    ----------
    joint : Element
        A movable ``<joint>`` that passed :func:`check_urdf_tree`.
    nv : int
        Its number of velocity coordinates in the model.
    where : Site
        Its ``<limit>``, for error messages.

    Returns
    -------
    FileLimits
        Continuous joints without ``<limit>``, and floating and planar joints
        (whose ``<limit>`` URDF does not define and Pinocchio ignores), have
        infinite velocity and effort limits.
    """
    limit, jtype = joint.find("limit"), joint.get("type", "")
    units = _LIMIT_UNITS.get(jtype, ("", "", ""))
    unbounded = np.full(nv, np.inf)
    if limit is None or jtype not in _LIMIT_UNITS:
        return FileLimits(None, unbounded, unbounded, units)
    lower, upper, velocity, effort = (
        parse_number(limit.get(k, "0"), where, k) for k in ("lower", "upper", "velocity", "effort")
    )
    position = (lower, upper) if jtype != "continuous" else None
    return FileLimits(position, np.full(nv, velocity), np.full(nv, effort), units)


def _rotation_rpy(rpy: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw (fixed axes x, y, z) to a rotation matrix: Rz(y) Ry(p) Rx(r)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def _vector(elem: etree._Element | None, attr: str, where: Site) -> np.ndarray:
    text = elem.get(attr, "0 0 0") if elem is not None else "0 0 0"
    return np.array([parse_number(x, where, attr) for x in text.split()])


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def file_inertia(
    inertial: etree._Element, rotation: np.ndarray, translation: np.ndarray, where: Site
) -> np.ndarray:
    """Return the 6x6 spatial inertia of a checked ``<inertial>`` block in a joint frame.

    Layout as Pinocchio's ``Inertia.matrix()`` (linear first):
    ``[[m 1, -m [c]], [m [c], I_c - m [c]^2]]`` with ``c`` the centre of mass
    in [m] and ``I_c`` the rotational inertia at the centre of mass in
    [kg m^2], both in joint-frame axes.

    Parameters
    ----------
    inertial : Element
        An ``<inertial>`` that passed :func:`check_urdf_tree`.
    rotation : ndarray, shape (3, 3)
        Orientation of the link frame in the joint frame.
    translation : ndarray, shape (3,)
        Position of the link frame in the joint frame, in [m].
    where : Site
        The link, for error messages.

    Returns
    -------
    ndarray, shape (6, 6)
        The spatial inertia; zero for a massless link. Entries are not finite
        when an ``<origin>`` is so far out that ``m |c|^2`` overflows (the
        caller reports it).
    """
    origin = inertial.find("origin")
    mass_elem, inertia_elem = inertial.find("mass"), inertial.find("inertia")
    assert mass_elem is not None and inertia_elem is not None  # checked by the tree rules
    mass = parse_number(mass_elem.get("value"), where, "value")
    ixx, ixy, ixz, iyy, iyz, izz = (
        parse_number(inertia_elem.get(k), where, k) for k in _INERTIA_KEYS
    )
    axes = rotation @ _rotation_rpy(_vector(origin, "rpy", where))
    if mass == 0:  # Pinocchio keeps a massless body's rotational inertia, wherever it is
        out = np.zeros((6, 6))
        out[3:, 3:] = axes @ np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]) @ axes.T
        return out
    with np.errstate(over="ignore", invalid="ignore"):  # huge origins: the caller reports
        com = rotation @ _vector(origin, "xyz", where) + translation
        i_com = axes @ np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]) @ axes.T
        cross = _skew(com)
        return np.block(
            [[mass * np.eye(3), -mass * cross], [mass * cross, i_com - mass * cross @ cross]]
        )


class InertiaFinding(NamedTuple):
    """A physically implausible ``<inertial>`` (it breaks a plausibility rule).

    Attributes
    ----------
    link : str
        Name of the link.
    where : Site
        Its ``<inertia>`` element (file, element, line), for messages.
    problem : str
        What is wrong, with the values.
    rule : str
        The rule, in words.
    mass : float
        The link's mass in [kg].
    inertia : ndarray, shape (3, 3)
        Its rotational inertia at the centre of mass, in [kg m^2] (``<inertia>`` axes).
    """

    link: str
    where: Site
    problem: str
    rule: str
    mass: float
    inertia: np.ndarray


def _plausibility(mass: float, inertia: np.ndarray) -> tuple[str, str] | None:
    """Return ``(problem, rule)`` for an implausible mass and inertia, else None."""
    if mass == 0:
        if np.any(inertia != 0):
            return "a massless link has non-zero inertia", "mass = 0 implies inertia = 0"
        return None
    moments = np.linalg.eigvalsh(inertia)  # ascending principal moments [kg m^2]
    tol = _INERTIA_RTOL * abs(float(np.trace(inertia))) + _INERTIA_ATOL
    if moments[0] < -tol:
        problem = f"principal moments {moments.tolist()} kg m^2 include a negative one"
        return problem, "inertia is positive semidefinite"
    if moments[0] + moments[1] < moments[2] - tol:
        problem = f"principal moments {moments.tolist()} kg m^2 violate I1 + I2 >= I3"
        return problem, "principal moments obey the triangle inequality"
    return None


def implausible_inertias(tree: etree._ElementTree, path: str) -> tuple[InertiaFinding, ...]:
    """Return every link whose ``<inertial>`` breaks a plausibility rule.

    With ``m`` the mass and ``I`` the rotational inertia at the centre of mass:
    a link with ``m = 0`` must have ``I = 0``; for ``m > 0`` the principal
    moments ``I1 <= I2 <= I3`` must be ``>= 0`` and obey the triangle
    inequality ``I1 + I2 >= I3``. Point masses and thin rods (semidefinite
    ``I``) are plausible. :func:`welded_links` names the links that cannot
    move in the fixed-base model, where such an inertia cannot change any result.

    Parameters
    ----------
    tree : lxml.etree._ElementTree
        A tree that passed :func:`check_urdf_tree`.
    path : str
        Its file, for messages.

    Returns
    -------
    tuple of InertiaFinding
        In document order; empty when every inertia is plausible.
    """
    found = []
    for link in root_of(tree, path).findall("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        owner = f"link {link.get('name')!r}"
        mass_elem, inertia_elem = inertial.find("mass"), inertial.find("inertia")
        assert mass_elem is not None and inertia_elem is not None  # checked by the tree rules
        where = site(path, inertia_elem, owner)
        mass = parse_number(mass_elem.get("value"), where, "value")
        ixx, ixy, ixz, iyy, iyz, izz = (
            parse_number(inertia_elem.get(k), where, k) for k in _INERTIA_KEYS
        )
        inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        verdict = _plausibility(mass, inertia)
        if verdict is not None:
            found.append(InertiaFinding(link.get("name", ""), where, *verdict, mass, inertia))
    return tuple(found)


def welded_links(
    tree: etree._ElementTree, path: str, locked: frozenset[str] = frozenset()
) -> frozenset[str]:
    """Return the links that cannot move in the fixed-base model.

    A link is welded to the world when every joint between it and the root
    link is ``fixed`` or named in ``locked``.

    Parameters
    ----------
    tree : lxml.etree._ElementTree
        A tree that passed :func:`check_urdf_tree` (one root, no loops).
    path : str
        Its file, for messages.
    locked : frozenset of str
        Movable joints that will be locked (they count as fixed).

    Returns
    -------
    frozenset of str
        Names of the welded links, the root link included.
    """
    robot = root_of(tree, path)
    parent_of: dict[str, tuple[str, bool]] = {}  # child -> (parent, joint is rigid)
    for joint in robot.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        assert parent is not None and child is not None  # checked by the tree rules
        rigid = joint.get("type") == "fixed" or joint.get("name") in locked
        parent_of[child.get("link", "")] = (parent.get("link", ""), rigid)
    welded: set[str] = set()
    for link in robot.findall("link"):
        name, chain = link.get("name", ""), []
        while name in parent_of and parent_of[name][1] and name not in welded:
            chain.append(name)
            name = parent_of[name][0]
        if name in welded or name not in parent_of:  # reached the root through rigid joints
            welded.update(chain)
            welded.add(name)
    return frozenset(welded)


def check_mimic_graph(joints: dict[str, etree._Element], path: str) -> None:
    """Refuse mimic relations that do not define each mimic joint by a free joint.

    A ``<mimic joint="j">`` must name a defined, movable joint that does not
    itself mimic another: chains (a mimics b, b mimics c) and cycles (a mimics
    b, b mimics a) would otherwise load as independent joints.

    Parameters
    ----------
    joints : dict of str to Element
        The ``<joint>`` elements by name (unique names, checked).
    path : str
        The file, for error messages.

    Raises
    ------
    URDFStructureError
        Naming the joints of the unknown target, chain or cycle.
    """
    target = {
        name: mimic.get("joint", "")
        for name, joint in joints.items()
        if (mimic := joint.find("mimic")) is not None
    }
    rule = "a mimic joint follows a defined movable joint that mimics no other (no chain or cycle)"
    for name, mimicked in target.items():
        mimic = joints[name].find("mimic")
        assert mimic is not None  # a key of target
        mimic_site = site(path, mimic, f"joint {shorten(name)}")
        if mimicked not in joints or mimicked == name:
            raise _broken(mimic_site, f"mimics {shorten(mimicked)}, not another joint", rule)
        if joints[mimicked].get("type") == "fixed":
            raise _broken(mimic_site, f"mimics the fixed joint {shorten(mimicked)}", rule)
        if mimicked not in target:
            continue
        path_of, link = [name], mimicked
        while link in target and link not in path_of:
            path_of.append(link)
            link = target[link]
        if link in path_of:
            cycle = " -> ".join(shorten(j) for j in [*path_of[path_of.index(link) :], link])
            raise _broken(mimic_site, f"is part of the mimic cycle {cycle}", rule)
        chain = " -> ".join(shorten(j) for j in [*path_of, link])
        problem = f"mimics {shorten(mimicked)}, which mimics another joint: the chain {chain}"
        raise _broken(mimic_site, problem, rule)
