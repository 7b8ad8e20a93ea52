"""Strict, safe loading of a URDF file into Pinocchio: :func:`load_urdf_strict` (issue 6, item 1).

The pipeline raises at the first broken rule: size (:mod:`.size`), strict XML
(:mod:`.xml`), tree and physics rules (:mod:`.rules`; implausible inertias under
:func:`inertia_policy`), mesh and texture paths inside ``package_dirs``
(:mod:`.resources`), Pinocchio built from the checked tree, and
:func:`check_model` (the model against the file, finite and defined dynamics).
The steps are listed in :func:`load_urdf_strict`; why a singular ``M(q)`` is
refused is in docs/design.md, "Module notes".

>>> loaded = load_urdf_strict("robot.urdf", package_dirs=["."])  # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import tempfile
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import numpy as np
import pinocchio as pin
from lxml import etree

from youbot_opt.exceptions import (
    InvalidModelError,
    ModelError,
    ParameterError,
    RobotNotFound,
    UnsafeURDFError,
    URDFError,
    YoubotOptWarning,
)
from youbot_opt.robot.model import LazyGeometry
from youbot_opt.robot.urdf_check.dynamics_defined import check_dynamics_defined
from youbot_opt.robot.urdf_check.geometry_cache import mesh_loader
from youbot_opt.robot.urdf_check.resources import (
    allowed_roots,
    check_mesh,
    in_mesh,
    read_regular_file,
    resolve_reference,
)
from youbot_opt.robot.urdf_check.rules import (
    InertiaFinding,
    check_urdf_tree,
    file_inertia,
    file_limits,
    implausible_inertias,
    resource_references,
    welded_links,
)
from youbot_opt.robot.urdf_check.size import SizeLimits, check_urdf_size
from youbot_opt.robot.urdf_check.xml import Site, fail, parse_xml_strict, root_of, site

__all__ = [
    "LoadedURDF",
    "VisualBuilder",
    "locked_reference",
    "MAX_URDF_BYTES",
    "load_urdf_strict",
    "read_description",
    "check_urdf_text",
    "check_model",
    "inertia_policy",
]

logger = logging.getLogger(__name__)

#: Largest URDF file accepted, in [bytes].
MAX_URDF_BYTES: int = 64 * 2**20
#: Random configurations at which M(q) must be positive definite (plus neutral).
_N_MASS_MATRIX_SAMPLES = 8
#: M(q) counts as singular when its smallest eigenvalue is below this fraction
#: of its largest: CRBA round-off is ~1e-16 of the largest, so the bound leaves
#: four orders of margin while any real arm (condition number < 1e12) passes.
_MASS_MATRIX_RCOND = 1e-12
#: Relative tolerance between the file's inertias and the model's: the two
#: sums differ only by floating-point reassociation (~1e-15).
_INERTIA_MATCH_RTOL = 1e-10
#: Relative tolerance between the file's joint limits and the model's: both are
#: the same decimal text read by correctly rounded parsers (urdfdom and
#: :func:`~youbot_opt.robot.urdf_check.xml.parse_number`), so they agree exactly; 1e-12
#: only allows a last-bit difference, far below any intended change of a limit.
_LIMIT_MATCH_RTOL = 1e-12
#: Rule of the finiteness checks (item 3 of the audit: a huge ``<origin>``).
_FINITE_RULE = "every <origin> is in range: placements, spatial inertias and M(q) are finite"


@dataclass(frozen=True, kw_only=True)
class LoadedURDF:
    """A URDF file that passed every rule, loaded into Pinocchio.

    Attributes
    ----------
    model : pinocchio.Model
        Kinematic and inertial model (fixed base, mimic joints as ordinary joints).
    visual_model : pinocchio.GeometryModel
        Visual geometries; mesh paths are the checked absolute paths. Under
        ``load_urdf_strict(defer_visual=True)`` built (its meshes read) on its
        first read, by a :class:`VisualBuilder`.
    collision_model : pinocchio.GeometryModel
        Collision geometries; mesh paths are the checked absolute paths.
    path : Path
        The URDF file, absolute.
    resources : tuple of Path
        Every file the description references and that was checked (meshes,
        and the textures and material libraries they reference), real paths.
    """

    model: pin.Model
    visual_model: pin.GeometryModel = field(  # noqa: RUF009
        default=LazyGeometry("visual_model"), compare=False
    )
    collision_model: pin.GeometryModel
    path: Path
    resources: tuple[Path, ...] = ()


_T = TypeVar("_T")


def _built_by_pinocchio(name: str, build: Callable[[], _T]) -> _T:
    """Return ``build()``, Pinocchio's parser output logged; its refusal an InvalidModelError."""
    error: Exception | None = None
    with _c_stderr_captured() as report:
        try:
            built = build()
        except (ValueError, RuntimeError) as e:
            error = e
    parser_output = report[0] if report else ""
    if error is not None:
        problem = (
            f"Pinocchio refused the checked description: {error}; "
            f"its parser said: {parser_output or '-'}"
        )
        raise fail(
            InvalidModelError, Site(name, "<robot>", None), problem, "Pinocchio builds the model"
        ) from error
    if parser_output:
        logger.warning("Pinocchio's URDF parser reported for %s: %s", name, parser_output)
    return built


def locked_reference(
    model: pin.Model, locked: Sequence[tuple[str, float]]
) -> tuple[list[int], np.ndarray]:
    """Return the joint ids of ``locked`` and the configuration holding them, for a reduced model.

    Parameters
    ----------
    model : pinocchio.Model
        The full model.
    locked : sequence of (str, float)
        Joint names and positions in [rad] (or [m]); a continuous joint's angle.

    Returns
    -------
    ids : list of int
        The joints' indices in ``model``.
    q_ref : ndarray, shape (model.nq,)
        The neutral configuration with each locked joint at its position.
    """
    q_ref = pin.neutral(model)
    ids = []
    for name, value in locked:
        jid = model.getJointId(name)
        joint = model.joints[jid]
        if joint.nq == 1:
            q_ref[joint.idx_q] = value
        else:  # continuous: (cos, sin) of the angle
            q_ref[joint.idx_q : joint.idx_q + 2] = (math.cos(value), math.sin(value))
        ids.append(jid)
    return ids, q_ref


@dataclass(frozen=True)
class VisualBuilder:
    """Builds the visual geometry of a checked URDF (its meshes read), when first drawn.

    :func:`load_urdf_strict` checks every reference at load; this reads the
    meshes. A picklable value (text and paths): a robot sent to another process
    carries it, not the meshes.

    Attributes
    ----------
    text : str
        The checked description, each mesh and texture reference replaced by its
        checked absolute path.
    package_dirs : tuple of str
        The folders references resolve in.
    meshes : tuple of str
        The mesh files the description references (checked for changes by the
        mesh cache, :func:`~youbot_opt.robot.urdf_check.geometry_cache.mesh_loader`).
    path : str
        The file, for messages.
    locked : tuple of (str, float)
        Joints held at a position in [rad] or [m]: the geometry of the reduced
        model (:func:`locked_reference`).
    """

    text: str
    package_dirs: tuple[str, ...]
    meshes: tuple[str, ...]
    path: str
    locked: tuple[tuple[str, float], ...] = ()

    def __call__(self) -> pin.GeometryModel:
        """Build the visual geometry model (of the reduced model when joints are locked).

        Raises
        ------
        InvalidModelError
            If Pinocchio refuses a visual mesh (a URDFError naming the file).
        """

        def build() -> tuple[pin.Model, pin.GeometryModel]:
            with mesh_loader(self.meshes) as loader:
                model = pin.buildModelFromXML(self.text)
                visual = pin.buildGeomFromUrdfString(
                    model,
                    self.text,
                    pin.GeometryType.VISUAL,
                    package_dirs=list(self.package_dirs),
                    mesh_loader=loader,
                )
            return model, visual

        model, visual = _built_by_pinocchio(self.path, build)
        if not self.locked:
            return visual
        ids, q_ref = locked_reference(model, self.locked)
        _, (reduced,) = pin.buildReducedModel(model, [visual], ids, q_ref)
        return reduced


def read_description(
    path: str | os.PathLike[str], kind: str, size_limits: SizeLimits
) -> etree._ElementTree:
    """Read a robot description file (URDF, MJCF) as a hostile file and parse it strictly.

    The file must exist and be a regular file of at most :data:`MAX_URDF_BYTES`
    [bytes]; its XML is parsed with every ``DOCTYPE`` and entity refused, under
    the nesting and element limits of ``size_limits``.

    Parameters
    ----------
    path : path-like
        The file.
    kind : str
        What the file is (``"URDF"``, ``"MJCF"``), for the messages.
    size_limits : SizeLimits
        Its ``max_xml_depth`` [levels] and ``max_xml_elements`` [count] apply
        (None: the environment variable's or the default).

    Returns
    -------
    lxml.etree._ElementTree
        The parsed file; each element has a ``sourceline`` (1-based line).

    Raises
    ------
    RobotNotFound
        ``"<kind> file '<path>' does not exist"``.
    ModelError
        ``"cannot read <kind> file '<path>': <reason>"`` (permissions).
    UnsafeURDFError
        Not a regular file, larger than :data:`MAX_URDF_BYTES`, a ``DOCTYPE``,
        or too deep or too many elements.
    URDFSyntaxError
        Malformed XML.
    """
    name = os.fspath(path)
    if not os.path.exists(name):
        raise RobotNotFound(f"{kind} file {name!r} does not exist", path=name)
    try:
        data = read_regular_file(
            Path(name), MAX_URDF_BYTES, Site(name, "file", None), kind, UnsafeURDFError
        )
    except OSError as e:
        raise ModelError(f"cannot read {kind} file {name!r}: {e}", path=name) from e
    return parse_xml_strict(
        data,
        name,
        max_depth=size_limits.max_xml_depth,
        max_elements=size_limits.max_xml_elements,
    )


def _read_and_check(
    path: str | os.PathLike[str],
    package_dirs: Sequence[str | os.PathLike[str]],
    *,
    strict: bool = True,
    locked: frozenset[str] = frozenset(),
    size_limits: SizeLimits | None = None,
) -> tuple[etree._ElementTree, list[tuple[etree._Element, str, Path]], tuple[Path, ...]]:
    sizes = size_limits if size_limits is not None else SizeLimits()
    if not isinstance(sizes, SizeLimits):
        raise ParameterError(
            f"size_limits must be a SizeLimits or None, got {type(size_limits).__name__}",
            name="size_limits",
            value=size_limits,
        )
    roots = allowed_roots(package_dirs)
    name = os.fspath(path)
    tree = read_description(name, "URDF", sizes)
    # before the quadratic rules and Pinocchio's recursive parser
    check_urdf_size(
        tree, name, max_joints=sizes.max_joints, max_depth=sizes.max_tree_depth,
        max_dof=sizes.max_dof,
    )  # fmt: skip
    check_urdf_tree(tree, name)
    inertia_policy(tree, name, strict=strict, locked=locked)
    references: list[tuple[etree._Element, str, Path]] = []
    resources: list[Path] = []
    for elem, kind, where in resource_references(tree, name):
        real = resolve_reference(elem.get("filename", ""), roots, roots, where)
        references.append((elem, "filename", real))
        resources.append(real)
        if kind == "mesh":
            try:
                resources.extend(check_mesh(real, roots, where))
            except URDFError as e:
                if e.path == where.path:  # already names the URDF element
                    raise
                raise in_mesh(e, where, real) from e
    logger.debug("%s: %d resources checked", name, len(resources))
    return tree, references, tuple(dict.fromkeys(resources))


def check_urdf_text(
    path: str | os.PathLike[str],
    package_dirs: Sequence[str | os.PathLike[str]],
    *,
    size_limits: SizeLimits | None = None,
) -> etree._ElementTree:
    """Run every check that needs only the file (steps 1-4 of :func:`load_urdf_strict`).

    Parameters
    ----------
    path : path-like
        The URDF file.
    package_dirs : sequence of path-like
        Folders meshes and textures may come from; ``package://pkg/...``
        resolves to the first ``dir/pkg/...`` that exists.
    size_limits : SizeLimits, optional
        Size limits of the file (counts); by default the environment
        variables' or the module constants.

    Returns
    -------
    lxml.etree._ElementTree
        The parsed file; each element has a ``sourceline`` (1-based line).

    Raises
    ------
    RobotNotFound
        If ``path`` does not exist.
    ModelError
        If ``path`` cannot be read (permissions).
    URDFError
        One of its subclasses, naming the file, element, line and rule.
    ParameterError
        If a package directory is not an existing folder, or a size limit is not
        an integer >= 1.
    """
    return _read_and_check(path, package_dirs, size_limits=size_limits)[0]


@contextlib.contextmanager
def _c_stderr_captured() -> Iterator[list[str]]:
    """Capture what C code writes on file descriptor 2 (not thread-safe)."""
    captured: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to capture
        yield captured
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield captured
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            captured.append(sink.read().decode("utf-8", errors="replace").strip())


def _check_joints(model: pin.Model, robot: etree._Element, path: str) -> None:
    movable = [j.get("name", "") for j in robot.findall("joint") if j.get("type") != "fixed"]
    in_model = list(model.names)[1:]
    if sorted(movable) != sorted(in_model):
        problem = f"file has movable joints {sorted(movable)}, model has {sorted(in_model)}"
        raise fail(
            InvalidModelError,
            Site(path, "<robot>", None),
            problem,
            "the model has the file's joints",
        )


def _check_placements(model: pin.Model, path: str) -> None:
    """Require finite joint and frame placements (sums of huge fixed-joint origins overflow)."""
    placements = [
        (f"joint {n!r}", p) for n, p in zip(model.names, model.jointPlacements, strict=True)
    ]
    placements += [(f"frame {f.name!r}", f.placement) for f in model.frames]
    for what, placement in placements:
        if not np.all(np.isfinite(placement.homogeneous)):
            problem = (
                f"the placement of {what} in the model is not finite "
                f"(translation {placement.translation.tolist()} m): its <origin>s are out of range"
            )
            raise fail(InvalidModelError, Site(path, "<robot>", None), problem, _FINITE_RULE)


def _check_limits(model: pin.Model, robot: etree._Element, path: str) -> None:
    """Compare each movable joint's position, velocity and effort limits with the file."""
    rule = "the model's joint limits are the file's <limit> (lower, upper, velocity, effort)"
    for joint in robot.findall("joint"):
        jtype, name = joint.get("type", ""), joint.get("name", "")
        if jtype == "fixed":
            continue
        joint_id = model.getJointId(name)
        nv = model.nvs[joint_id]
        if nv == 0:  # a mimic joint built with mimic=True: it has no own coordinates
            continue
        limit = joint.find("limit")
        where = site(path, limit, f"joint {name!r}") if limit is not None else site(path, joint)
        position, velocity, effort, units = file_limits(joint, nv, where)
        iq, iv = model.idx_qs[joint_id], model.idx_vs[joint_id]
        compared = [
            ("velocity limit (on |v|)", velocity, model.velocityLimit[iv : iv + nv], units[1]),
            ("effort limit (on |tau|)", effort, model.effortLimit[iv : iv + nv], units[2]),
        ]
        if position is not None:
            compared[:0] = [
                (f"{side} position limit", np.array([bound]), limits[iq : iq + 1], units[0])
                for side, bound, limits in (
                    ("lower", position[0], model.lowerPositionLimit),
                    ("upper", position[1], model.upperPositionLimit),
                )
            ]
        for quantity, want, have, unit in compared:
            if np.all(np.isclose(want, have, rtol=_LIMIT_MATCH_RTOL, atol=0.0)):
                continue
            unit = f" {unit}" if unit else ""
            in_file = f"{want.tolist()}{unit}" if np.all(np.isfinite(want)) else "no limit"
            problem = (
                f"{jtype} joint {name!r} has the {quantity} {have.tolist()}{unit} "
                f"in the model, but the file gives {in_file}"
            )
            raise fail(InvalidModelError, where, problem, rule)


def _check_inertias(model: pin.Model, robot: etree._Element, path: str) -> None:
    expected = [np.zeros((6, 6)) for _ in range(model.njoints)]
    for link in robot.findall("link"):
        where = site(path, link)
        frame_id = model.getFrameId(link.get("name"), pin.FrameType.BODY)
        if frame_id >= len(model.frames):
            raise fail(
                InvalidModelError, where, "is not a body of the model", "every link is in the model"
            )
        inertial = link.find("inertial")
        if inertial is not None:
            frame = model.frames[frame_id]
            block = file_inertia(
                inertial, frame.placement.rotation, frame.placement.translation, where
            )
            if not np.all(np.isfinite(block)):
                distance = np.abs(block[3:, :3]).max() / block[0, 0]  # max |c_i| of m [c]
                problem = (
                    f"its centre of mass lies {distance:.3g} m from the frame of joint "
                    f"{model.names[frame.parentJoint]!r} (its <origin>, or those of the fixed "
                    "joints between, are out of range): the 6x6 spatial inertia there, with "
                    "terms m |c|^2, is not finite"
                )
                owner = f"link {link.get('name')!r}"
                raise fail(InvalidModelError, site(path, inertial, owner), problem, _FINITE_RULE)
            expected[frame.parentJoint] += block
    rule = "every <inertial> of the file is in the model, unchanged"
    for joint_id, (want, got) in enumerate(zip(expected, model.inertias, strict=True)):
        with np.errstate(over="ignore", invalid="ignore"):
            have = got.matrix()
        if not (np.all(np.isfinite(want)) and np.all(np.isfinite(have))):
            problem = (
                f"the spatial inertia of the body of joint {model.names[joint_id]!r} is not "
                f"finite (in the file: {np.all(np.isfinite(want))}, in the model: "
                f"{np.all(np.isfinite(have))}): its links' <origin>s are out of range"
            )
            raise fail(InvalidModelError, Site(path, "<robot>", None), problem, _FINITE_RULE)
        scale = max(np.abs(want).max(), np.abs(have).max())
        if np.abs(want - have).max() > _INERTIA_MATCH_RTOL * scale:
            problem = (
                f"body of joint {model.names[joint_id]!r} has mass {got.mass} kg in the model, but "
                f"its links' <inertial> blocks add up to {want[0, 0]} kg (6x6 spatial inertias "
                f"differ by {np.abs(want - have).max():.3g})"
            )
            raise fail(InvalidModelError, Site(path, "<robot>", None), problem, rule)


def _check_mass_matrix(model: pin.Model, path: str) -> None:
    if model.nv == 0:
        return
    data = model.createData()
    rng = np.random.default_rng(0)
    neutral = pin.neutral(model)
    configurations = [neutral] + [
        pin.integrate(model, neutral, rng.uniform(-np.pi, np.pi, model.nv))
        for _ in range(_N_MASS_MATRIX_SAMPLES)
    ]
    for sample, q in enumerate(configurations):
        where = "the neutral configuration" if sample == 0 else f"random configuration {sample}"
        upper = pin.crba(model, data, q)
        mass_matrix = np.triu(upper) + np.triu(upper, 1).T
        if not np.all(np.isfinite(mass_matrix)):
            pin.framesForwardKinematics(model, data, q)
            reach = max(np.abs(placement.translation).max() for placement in data.oMf)
            problem = (
                f"the joint space inertia matrix M(q) is not finite at {where}: joint "
                f"<origin>s are out of range (bodies up to {reach:.3g} m from the base, "
                "so the terms m r^2 overflow)"
            )
            raise fail(InvalidModelError, Site(path, "<robot>", None), problem, _FINITE_RULE)
        eigenvalues, eigenvectors = np.linalg.eigh(mass_matrix)
        if eigenvalues[0] > _MASS_MATRIX_RCOND * eigenvalues[-1] and eigenvalues[-1] > 0:
            continue
        weak = np.abs(eigenvectors[:, 0]) > 1e-3  # joints taking part in the inertia-free motion
        joints = sorted(
            model.names[j]
            for j in range(1, model.njoints)
            if np.any(weak[model.idx_vs[j] : model.idx_vs[j] + model.nvs[j]])
        )
        problem = (
            f"the joint space inertia matrix M(q) is singular at {where}: "
            f"eigenvalues from {eigenvalues[0]:.3g} to {eigenvalues[-1]:.3g}; "
            f"joints {joints} move without inertia (e.g. a massless link at the end of a chain)"
        )
        rule = "M(q) is positive definite (forward dynamics are defined)"
        raise fail(InvalidModelError, Site(path, "<robot>", None), problem, rule)


def check_model(model: pin.Model, tree: etree._ElementTree, path: str | os.PathLike[str]) -> None:
    """Check a loaded model against its file and require defined dynamics.

    Parameters
    ----------
    model : pinocchio.Model
        The model Pinocchio built from the file.
    tree : lxml.etree._ElementTree
        The parsed file, from :func:`check_urdf_text`.
    path : path-like
        The file, for error messages.

    Raises
    ------
    InvalidModelError
        If the model's joints are not the file's movable joints; a joint's
        position limits (revolute and prismatic), velocity limit (symmetric, on
        ``|v|``) or effort limit differ from its ``<limit>`` (``inf`` where the
        file gives none: continuous joints without ``<limit>``, floating and
        planar joints; mimic joints built with ``mimic=True`` have no own
        limits and are skipped); a link is missing; an ``<origin>`` is so far
        out that a placement, a spatial inertia or ``M(q)`` is not finite; the
        mass and inertia of a body differ from the sum of its links'
        ``<inertial>`` blocks in the file (Pinocchio silently drops a block it
        cannot parse); or ``M(q)`` is not positive definite (see Notes).

    Notes
    -----
    A model is accepted only if its joint space inertia matrix ``M(q)`` is
    positive definite, checked at the neutral configuration and at 8 seeded
    random ones. A movable joint whose subtree carries no inertia about its
    axis (e.g. a massless link at the end of a chain) makes ``M`` singular,
    so forward dynamics are undefined; such a file is refused, naming the
    joints. Massless links attached by *fixed* joints are fine: they add nothing.
    """
    name = os.fspath(path)
    robot = root_of(tree, name)
    _check_joints(model, robot, name)
    _check_limits(model, robot, name)
    _check_placements(model, name)
    _check_inertias(model, robot, name)
    _check_mass_matrix(model, name)
    check_dynamics_defined(model, name)  # RNEA, CRBA, ABA, M^-1 finite (issue 16)


def load_urdf_strict(
    path: str | os.PathLike[str],
    package_dirs: Sequence[str | os.PathLike[str]],
    *,
    strict: bool = True,
    locked: frozenset[str] = frozenset(),
    size_limits: SizeLimits | None = None,
    defer_visual: bool = False,
) -> LoadedURDF:
    """Check a URDF file, load it into Pinocchio and check the result.

    The steps, each raising at the first broken rule:

    1. The file must be a regular file of at most :data:`MAX_URDF_BYTES`
       (:class:`~youbot_opt.exceptions.UnsafeURDFError`; a missing file raises
       :class:`~youbot_opt.exceptions.RobotNotFound`).
    2. Strict XML parsing with every ``DOCTYPE`` and entity refused
       (:mod:`youbot_opt.robot.urdf_check.xml`).
    3. Tree and physics rules on the file's text (:mod:`youbot_opt.robot.urdf_check.rules`).
       Physically implausible inertias (:func:`~.rules.implausible_inertias`)
       follow :func:`inertia_policy`: on a link welded to the world a warning; on
       a moving link a refusal, or a warning under ``strict=False``.
    4. Mesh and texture references, including the textures inside ``.dae`` files,
       must resolve to regular files inside ``package_dirs``
       (:mod:`youbot_opt.robot.urdf_check.resources`).
    5. Pinocchio builds the model from the *checked tree*, re-serialised with each
       mesh and texture reference replaced by its checked absolute path: it reads
       exactly what was checked, never resolves a path itself and never consults
       ``ROS_PACKAGE_PATH``. What Pinocchio's URDF parser prints on the C-level
       standard error is captured and logged (or put in the error message).
    6. :func:`check_model` compares the model with the file (joints, joint limits,
       inertias), requires finite placements, inertias and ``M(q)`` (a huge
       ``<origin>`` makes them overflow) and defined dynamics.

    Parameters
    ----------
    path : path-like
        The URDF file.
    package_dirs : sequence of path-like
        Folders meshes and textures may come from; ``package://pkg/...``
        resolves to the first ``dir/pkg/...`` that exists.
    strict : bool
        Refuse an implausible inertia on a moving link (default); False loads
        it with a warning (:func:`inertia_policy`).
    locked : frozenset of str
        Movable joints the caller will lock: links behind them count as welded.
    size_limits : SizeLimits, optional
        Size limits of the file (counts of joints, degrees of freedom, chain
        length, XML nesting and elements); by default the environment
        variables' or the module constants (:class:`SizeLimits`).
    defer_visual : bool
        False (default): the visual geometry is built here. True: it is built
        (its meshes read) on its first read, by a :class:`VisualBuilder`; every
        reference is checked here either way, and the mesh files must still be
        there when it is read.

    Returns
    -------
    LoadedURDF
        Model, visual and collision geometry models, path and checked resources.

    Raises
    ------
    RobotNotFound
        If ``path`` does not exist.
    ModelError
        If ``path`` cannot be read (permissions).
    URDFError
        One of its subclasses (:class:`~youbot_opt.exceptions.URDFSyntaxError`,
        :class:`~youbot_opt.exceptions.UnsafeURDFError`,
        :class:`~youbot_opt.exceptions.UnsafePathError`,
        :class:`~youbot_opt.exceptions.ResourceNotFoundError`,
        :class:`~youbot_opt.exceptions.URDFStructureError`,
        :class:`~youbot_opt.exceptions.InvalidModelError`), naming the file,
        element, line and rule.
    ParameterError
        If a package directory is not an existing folder, or a size limit is not
        an integer >= 1.
    """
    name = os.fspath(path)
    tree, references, resources = _read_and_check(
        path, package_dirs, strict=strict, locked=locked, size_limits=size_limits
    )
    for elem, attr, real in references:
        elem.set(attr, os.fspath(real))
    text = etree.tostring(root_of(tree, name), encoding="unicode")
    dirs = [os.fspath(d) for d in allowed_roots(package_dirs)]
    meshes = tuple(os.fspath(real) for elem, _, real in references if elem.tag == "mesh")

    def build() -> tuple[pin.Model, pin.GeometryModel]:
        with mesh_loader(meshes) as loader:
            model = pin.buildModelFromXML(text)
            collision = pin.buildGeomFromUrdfString(
                model, text, pin.GeometryType.COLLISION, package_dirs=dirs, mesh_loader=loader
            )
        return model, collision

    model, collision = _built_by_pinocchio(name, build)
    check_model(model, tree, name)
    visual = VisualBuilder(text, tuple(dirs), meshes, name)
    return LoadedURDF(
        model=model,
        visual_model=visual if defer_visual else visual(),
        collision_model=collision,
        path=Path(name).absolute(),
        resources=resources,
    )


def _merged_into(robot: etree._Element, link: str) -> tuple[str, str]:
    """Return (link, joint) of the body ``link`` belongs to in the model ('' for the world)."""
    parent_joint = {
        j.find("child").get("link", ""): j  # type: ignore[union-attr]
        for j in robot.findall("joint")
    }
    while link in parent_joint and parent_joint[link].get("type") == "fixed":
        link = parent_joint[link].find("parent").get("link", "")  # type: ignore[union-attr]
    joint = parent_joint.get(link)
    return link, ("" if joint is None else joint.get("name", ""))


def _finding_text(finding: InertiaFinding) -> str:
    line = f":{finding.where.line}" if finding.where.line is not None else ""
    return (
        f"{finding.where.path}{line}: {finding.where.element}: {finding.problem} "
        f"[rule: {finding.rule}]"
    )


def _what_it_adds(robot: etree._Element, finding: InertiaFinding, welded: bool) -> str:
    body, joint = _merged_into(robot, finding.link)
    inertia = np.array2string(finding.inertia, precision=6, separator=", ").replace("\n", "")
    adds = f"{finding.mass:g} kg and rotational inertia {inertia} kg m^2 (about its centre of mass)"
    if welded:
        return (
            f"link {finding.link!r} is welded to the world in this fixed-base model, so it "
            f"changes no result; Pinocchio merges it into the world body (it adds {adds})"
        )
    if body == finding.link:
        return f"link {finding.link!r} is the body of moving joint {joint!r} ({adds})"
    return (
        f"link {finding.link!r} hangs on fixed joints from link {body!r}: Pinocchio merges it "
        f"into the body of moving joint {joint!r}, to which it adds {adds}"
    )


def inertia_policy(
    tree: etree._ElementTree,
    path: str | os.PathLike[str],
    *,
    strict: bool = True,
    locked: frozenset[str] = frozenset(),
) -> tuple[InertiaFinding, ...]:
    """Warn about or refuse the physically implausible inertias of a checked file.

    An implausible inertia (a massless link with inertia, a non positive
    semidefinite inertia, principal moments breaking the triangle inequality)
    on a link welded to the world (fixed joints, or joints in ``locked``, up to
    the root) cannot change a fixed-base result: a :class:`YoubotOptWarning`.
    On a moving link it enters ``M(q)``: refused unless ``strict`` is False,
    then a warning. Each message names file, element (the link), line and rule,
    and what Pinocchio adds to the body the link is merged into.

    Parameters
    ----------
    tree : lxml.etree._ElementTree
        A file that passed :func:`~youbot_opt.robot.urdf_check.rules.check_urdf_tree`.
    path : path-like
        The file, for messages.
    strict : bool
        Refuse implausible inertias on moving links (default).
    locked : frozenset of str
        Movable joints that will be locked.

    Returns
    -------
    tuple of InertiaFinding
        The implausible inertias that were accepted (each with a warning).

    Raises
    ------
    InvalidModelError
        ``strict`` and an implausible inertia on a moving link; the message
        says how to load it anyway.
    """
    name = os.fspath(path)
    findings = implausible_inertias(tree, name)
    if not findings:
        return ()
    robot = root_of(tree, name)
    welded = welded_links(tree, name, locked)
    for finding in findings:
        on_world = finding.link in welded
        effect = _what_it_adds(robot, finding, on_world)
        if not on_world and strict:
            problem = (
                f"{finding.problem}; {effect}, so it enters M(q). To load it anyway, with a "
                "warning, pass strict=False to load_model (command line: --lenient), or lock "
                "the joints it moves with"
            )
            raise fail(InvalidModelError, finding.where, problem, finding.rule)
        why = "" if on_world else "loaded because strict=False (--lenient), though it enters M(q): "
        warnings.warn(
            f"{_finding_text(finding)}; {why}{effect}",
            YoubotOptWarning,
            stacklevel=2,
        )
    return findings
