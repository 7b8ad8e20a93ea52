"""Save and load IK-path results: one JSON file with a schema name, version and checksum.

``save_result`` writes schema ``youbot_opt.ikpath_result``: a planar
method's result records its chain (targets, configurations, reported figures
and history), any other the robot's :class:`~youbot_opt.robot.source.RobotSource`,
a fingerprint of its kinematics, frame, targets, limits, ...; the body under
``"result"``, its SHA-256 under ``"sha256"``; writes are atomic. ``load_result``
rebuilds the problem, recomputes E, the target errors (Pinocchio) and the limit
violation, refuses a corrupt, newer, older (``scripts/migrate_0_1_0.py`` carries
those) or disagreeing file, and re-checks a claimed success.

>>> load_result(save_result(result, "path.json")).objective  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from youbot_opt._checks import to_float, to_int
from youbot_opt._files import (
    MIGRATION_SCRIPT,
    array_digest,
    atomic_write_bytes,
    check_schema_header,
    json_digest,
    read_regular_file,
    schema_header,
    software_versions,
)
from youbot_opt._typing import JSONDict
from youbot_opt.collision.clearance import (
    Clearance,
    ClearanceCertificate,
    clearance_document,
    clearance_from_document,
)
from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptError
from youbot_opt.ikpath.clearance import certify_path_clearance
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKPathResult, OuterIterate, build_result
from youbot_opt.ikpath.targets import Target, quaternion_to_matrix
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.planar import PlanarChain
from youbot_opt.robot.source import RobotSource

DEFAULT_LOAD_POSITION_TOL = 1e-6
"""The loader's position tolerance [m] of a target (:class:`Target`'s default)."""
DEFAULT_LOAD_ORIENTATION_TOL = 1e-6
"""The loader's orientation tolerance [rad] of a target (:class:`Target`'s default)."""
DEFAULT_LOAD_MARGIN = 0.0
"""The loader's clearance [m] of a path with a scene: no penetration (coal)."""

__all__ = [
    "COMPLEMENTARITY_TOL",
    "RECHECK_TOL",
    "SCHEMA",
    "SCHEMA_VERSION",
    "RobotSource",
    "encode_document",
    "encode_result",
    "finite_or_none",
    "history_from_json",
    "history_to_json",
    "limits_from_json",
    "limits_to_json",
    "load_result",
    "problem_spec",
    "problem_spec_3d",
    "read_document",
    "save_result",
    "write_document",
]

SCHEMA = "youbot_opt.ikpath_result"
"""Schema of an IK-path result file (a planar chain's or any robot's)."""
SCHEMA_VERSION = 2
"""The one version read: 1 (and the 3-D schema ``youbot_opt.spatial_ikpath_result``) was
written by 0.1.0 and is carried forward by ``scripts/migrate_0_1_0.py``."""
RECHECK_TOL = 1e-9
"""Largest accepted ``|stored - recomputed|`` of E [rad^2] and of the residuals or target
errors [m, rad] of an IK-path file: both come from the same float64 formulas, which agree
across CPUs to ~1e-15; a target moved by more than 1e-9 m (or a changed robot) is detected."""
COMPLEMENTARITY_TOL = 1e-9
"""Largest accepted ``nu_i |g_i|`` [rad^2], relative to ``max(1, E)``, of a file's clearance
multipliers against the recomputed rows ``g = rows(x) - margin`` of a claimed success: the
solvers stop with ``|g_i| <= 1e-10`` m on an active row (AL) or ``nu_i g_i`` near IPOPT's
final barrier parameter on an inactive one (measured on ur5 and a box: 1.5e-13 by IPOPT, 7e-18
by the AL, 7e-13 by the AL without its SQP phase)."""


def finite_or_none(x: float) -> float | None:
    """``float(x)``, or ``None`` (JSON ``null``) for an infinite or NaN ``x``."""
    return float(x) if math.isfinite(x) else None


def limits_to_json(values: Iterable[float]) -> list[float | None]:
    """JSON form of joint limits in [rad] or [m]: ``null`` for an infinite (absent) limit."""
    return [finite_or_none(v) for v in values]


def limits_from_json(values: Iterable[float | None], fill: float) -> np.ndarray:
    """Inverse of :func:`limits_to_json`: ``null`` becomes ``fill`` (``-inf`` or ``inf``)."""
    return np.array([fill if v is None else float(v) for v in values], dtype=float)


def history_to_json(history: Iterable[OuterIterate]) -> list[JSONDict]:
    """JSON form of the outer iterations of a result (non-finite figures as ``null``)."""
    return [
        {
            "iteration": h.iteration,
            "x": np.asarray(h.x).tolist(),
            "objective": finite_or_none(h.objective),
            "violation": finite_or_none(h.violation),
            "stationarity": finite_or_none(h.stationarity),
            "penalty": finite_or_none(h.penalty),
            "inner_iterations": h.inner_iterations,
        }
        for h in history
    ]


def history_from_json(
    items: Iterable[Mapping[str, object]], n_targets: int, n_joints: int
) -> tuple[OuterIterate, ...]:
    """Inverse of :func:`history_to_json`; each iterate's ``x`` shaped (n_targets, n_joints).

    Raises
    ------
    KeyError, TypeError, ValueError
        For a missing field or a value of the wrong shape or type.
    """

    def num(value: object) -> float:
        return math.nan if value is None else to_float(value)

    return tuple(
        OuterIterate(
            to_int(h["iteration"]),
            np.array(h["x"], dtype=float).reshape(n_targets, n_joints),
            num(h["objective"]),
            num(h["violation"]),
            num(h["stationarity"]),
            num(h["penalty"]),
            to_int(h["inner_iterations"]),
        )
        for h in items
    )


def encode_document(schema: str, version: int, body: Mapping[str, object]) -> bytes:
    """UTF-8 JSON of ``body`` under ``"result"``, behind the schema header and its SHA-256.

    Parameters
    ----------
    schema : str
        Schema name, e.g. :data:`SCHEMA`.
    version : int
        Schema version.
    body : dict
        JSON-ready content (no NaN or infinity).

    Returns
    -------
    bytes
        The document, with the Pinocchio and numpy versions that wrote it.
    """
    doc = {
        **schema_header(schema, version, software_versions(pin, np), sha256=json_digest(body)),
        "result": body,
    }
    return (json.dumps(doc, indent=1, allow_nan=False) + "\n").encode()


def write_document(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` (``.json`` appended if missing) atomically; return the file."""
    target = Path(path)
    if target.suffix != ".json":
        target = target.with_name(target.name + ".json")
    atomic_write_bytes(target, data)
    return target


def read_document(
    path: str | os.PathLike[str], *, schema: str, version: int, what: str, oldest: int = 1
) -> JSONDict:
    """Return the ``"result"`` body of a file written from :func:`encode_document`.

    Parameters
    ----------
    path : str or path-like
        The JSON file.
    schema : str
        The schema name the file must have.
    version : int
        The newest schema version this reader supports.
    what : str
        What the file holds, for messages (``"an IK-path result"``).
    oldest : int, optional
        The oldest schema version this reader supports (an older file is
        refused naming ``scripts/migrate_0_1_0.py``).

    Raises
    ------
    ResultFileError
        If the file is missing or not JSON, of another schema, of a newer, older
        (or invalid) schema version, or fails its checksum.
    """
    source = Path(path)
    try:
        doc = json.loads(read_regular_file(source, what=what).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ResultFileError(f"{source}: cannot read {what}: {exc}") from exc
    check_schema_header(doc, schema=schema, supported=version, source=str(source), oldest=oldest)
    body = doc.get("result")
    try:
        intact = isinstance(body, dict) and doc.get("sha256") == json_digest(body)
    except ValueError:  # a non-finite number: never written by save_result
        intact = False
    if not intact:
        raise ResultFileError(f"{source}: checksum mismatch; the file is corrupt")
    return body


def problem_spec(problem: CyclicIKProblem) -> JSONDict:
    """JSON-ready description of ``problem``: chain, targets and ``use_limits``.

    The form stored in result files (infinite limits as ``null``); sweeps put it
    in their manifest so that a resumed sweep is known to solve the same problem.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.

    Returns
    -------
    dict
        ``{"chain": {...}, "targets": [[x, y], ...], "use_limits": bool}``,
        lengths and targets in [m], limits in [rad].
    """
    chain = problem.planar_chain
    return {
        "chain": {
            "lengths": chain.lengths.tolist(),
            "q_lower": limits_to_json(chain.q_lower),
            "q_upper": limits_to_json(chain.q_upper),
            "base": chain.base.tolist(),
            "angle_offset": chain.angle_offset.tolist(),
            "name": chain.name,
            "tip_frame": chain.tip_frame,
        },
        "targets": problem.target_points.tolist(),
        "use_limits": problem.use_limits,
    }


def _planar_body(result: IKPathResult) -> dict[str, Any]:
    return {
        **problem_spec(result.problem),
        "method": result.method,
        "status": result.status.value,
        "configurations": result.configurations.tolist(),
        "objective": result.objective,
        "residuals": result.position_errors.tolist(),
        "limit_violation": result.limit_violation,
        "multipliers": result.multipliers.tolist(),
        "iterations": result.iterations,
        "inner_iterations": result.inner_iterations,
        "wall_time": result.wall_time,
        "message": result.message,
        "start": result.start.tolist(),
        "constraint_tol": result.constraint_tol,
        "history": history_to_json(result.history),
    }


def _certificate_json(cert: ClearanceCertificate | None) -> JSONDict | None:
    """Return :attr:`IKPathResult.clearance` for the file (None: no clearance)."""
    if cert is None:
        return None
    return {
        "certified": cert.certified,
        "margin_m": cert.margin,
        "tolerance_m": cert.tolerance,
        "lower_bound_m": cert.lower_bound,
        "closest_pair": list(cert.closest_pair),
        "closest_time": cert.closest_time,
        "closest_m": cert.closest_distance,
        "n_samples": cert.n_samples,
    }


def _parse_planar(body: dict[str, Any], constraint_tol: float) -> IKPathResult:
    spec = body["chain"]
    chain = PlanarChain(
        lengths=spec["lengths"],
        q_lower=limits_from_json(spec["q_lower"], -math.inf),
        q_upper=limits_from_json(spec["q_upper"], math.inf),
        base=spec["base"],
        angle_offset=spec["angle_offset"],
        name=str(spec["name"]),
        tip_frame=str(spec["tip_frame"]),
    )
    problem = CyclicIKProblem(
        robot=chain, targets=body["targets"], use_limits=bool(body["use_limits"])
    )
    history = history_from_json(body["history"], problem.n_targets, problem.n_joints)
    return build_result(
        problem,
        method=str(body["method"]),
        status=SolveStatus(body["status"]),
        x=np.array(body["configurations"], dtype=float),
        multipliers=np.array(body["multipliers"], dtype=float),
        iterations=int(body["iterations"]),
        inner_iterations=int(body["inner_iterations"]),
        wall_time=float(body["wall_time"]),
        message=str(body["message"]),
        start=np.array(body["start"], dtype=float),
        constraint_tol=constraint_tol,
        history=history,
    )


def _load_planar(source: Path, body: dict[str, Any], position_tol: float) -> IKPathResult:
    """Read a planar result's body; E and position errors recomputed and compared (1e-9).

    The success claim is re-checked at ``min(constraint_tol of the file, position_tol)``.
    """
    try:
        saved_tol = float(body["constraint_tol"])
        result = _parse_planar(body, min(saved_tol, position_tol))
        if not saved_tol <= position_tol:
            note = (
                f"checked at constraint_tol = {position_tol:.3g} m, not the file's {saved_tol:.3g}"
            )
            result = dataclasses.replace(result, message=f"{result.message}; {note}")
        stored_e = float(body["objective"])
        stored_res = np.array(body["residuals"], dtype=float)
    except (KeyError, TypeError, ValueError, YoubotOptError) as exc:
        raise ResultFileError(f"{source}: incomplete or invalid IK-path result: {exc}") from exc
    if stored_res.shape != result.position_errors.shape or not (
        abs(stored_e - result.objective) <= RECHECK_TOL
        and np.all(np.abs(stored_res - result.position_errors) <= RECHECK_TOL)
    ):
        raise ResultFileError(
            f"{source}: stored E = {stored_e!r} or residuals disagree with the ones recomputed "
            f"from the configurations (E = {result.objective!r}); the file is corrupt"
        )
    return result


def _kinematics_digest(model: pin.Model) -> str:
    """SHA-256 of the joint placements and position limits (what the kinematics depend on)."""
    placements = np.array([m.homogeneous for m in model.jointPlacements], dtype=float)
    frames = np.array([f.placement.homogeneous for f in model.frames], dtype=float)
    limits = np.stack([model.lowerPositionLimit, model.upperPositionLimit])
    return array_digest(np.concatenate([placements.ravel(), frames.ravel(), limits.ravel()]))


def problem_spec_3d(problem: CyclicIKProblem) -> JSONDict:
    """JSON-ready description of ``problem`` (result files and sweep manifests).

    Returns
    -------
    dict
        Model name, joint names and kinematics digest; frame, targets
        (:meth:`Target.to_dict`), ``use_limits``, limits in [rad] or
        [m] (``null``: unlimited) and joint weights.
    """
    model = problem.model
    return {
        "model": {
            "name": model.name,
            "joints": list(model.names),
            "kinematics_sha256": _kinematics_digest(model),
        },
        "frame": problem.frame,
        "joint_names": list(problem.joint_names),
        "targets": [t.to_dict() for t in problem.targets],
        "use_limits": problem.use_limits,
        "q_lower": limits_to_json(problem.q_lower),  # type: ignore[arg-type]
        "q_upper": limits_to_json(problem.q_upper),  # type: ignore[arg-type]
        "joint_weights": problem.weights.tolist(),
    }


def _clearance_json(problem: CyclicIKProblem, folder: Path | None) -> JSONDict | None:
    """Return the problem's clearance: scene, margin [m], pairs, leg samples (None: none)."""
    if problem.clearance is None:
        return None
    doc = clearance_document(problem.clearance, Path.cwd() if folder is None else folder)
    return {**doc, "leg_samples": problem.leg_samples}


def _clearance_of(desc: Any, robot: str, folder: Path) -> tuple[Clearance | None, dict[str, int]]:
    """Return the saved clearance and ``leg_samples`` keyword (None, {}: the problem had none)."""
    if desc is None:
        return None, {}
    spec = clearance_from_document(desc, robot, folder)
    return spec, {"leg_samples": int(desc["leg_samples"])}


def _body_3d(
    result: IKPathResult, robot: RobotSource | None, folder: Path | None
) -> dict[str, Any]:
    return {
        "robot": None if robot is None else robot.to_json(folder=folder),
        **problem_spec_3d(result.problem),
        "clearance": _clearance_json(result.problem, folder),
        "method": result.method,
        "status": result.status.value,
        "message": result.message,
        "configurations": result.configurations.tolist(),
        "objective": result.objective,
        "position_errors": result.position_errors.tolist(),
        "orientation_errors": result.orientation_errors.tolist(),
        "limit_violation": result.limit_violation,
        "multipliers": result.multipliers.tolist(),
        "iterations": result.iterations,
        "wall_time": result.wall_time,
        "start": result.start.tolist(),
        "history": history_to_json(result.history),
        # coal's certificate at the problem's margin, for the reader: load_result
        # recomputes it from the configurations, never reads it.
        "clearance_certificate": _certificate_json(result.clearance),
        # nu >= 0 [rad^2/m] per clearance row; data: load_result re-checks them
        "clearance_multipliers": (
            None if result.clearance_multipliers is None else result.clearance_multipliers.tolist()
        ),
    }


def _target(d: dict[str, Any]) -> Target:
    quat = d.get("quaternion_xyzw")
    approach = d.get("approach")
    extra: dict[str, Any] = {}
    if approach is not None and d.get("approach_axis") is not None:
        extra["approach_axis"] = np.array(d["approach_axis"], dtype=float)
    return Target(
        position=np.array(d["position"], dtype=float),
        rotation=None if quat is None else quaternion_to_matrix(quat),
        approach=None if approach is None else np.array(approach, dtype=float),
        position_tol=float(d["position_tol"]),
        orientation_tol=float(d["orientation_tol"]),
        orientation_weight=float(d["orientation_weight"]),
        **extra,
    )


def _model_of(
    body: dict[str, Any], robot: RobotModel | pin.Model | None, source: Path
) -> RobotModel | pin.Model:
    """Return the caller's robot, else the file's robot source loaded; check its fingerprint."""
    if robot is None:
        spec = body.get("robot")
        if spec is None:
            raise ResultFileError(
                f"{source}: the file names no robot source; pass robot= (the RobotModel or "
                "pinocchio.Model it was solved on)"
            )
        try:
            robot = RobotSource.from_json(spec).load(folder=source.parent)
        except YoubotOptError as exc:
            raise ResultFileError(
                f"{source}: cannot load the robot it was solved on: {exc}; pass robot= (the "
                "RobotModel to check it against, e.g. load_model(...) of an edited URDF if "
                "the change is intended)"
            ) from exc
    model = robot.model if isinstance(robot, RobotModel) else robot
    want = body["model"]
    if list(model.names) != list(want["joints"]) or _kinematics_digest(model) != str(
        want["kinematics_sha256"]
    ):
        raise ResultFileError(
            f"{source}: the robot differs from the one the result was solved on (model "
            f"{want['name']!r}, joints {want['joints']}; got {model.name!r}, joints "
            f"{list(model.names)}, or other joint placements/limits)"
        )
    return robot


def _fk_errors(problem: CyclicIKProblem, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-target position [m] and orientation [rad] errors by ``pin.framesForwardKinematics``."""
    data = problem.model.createData()
    pos, ang = [], []
    for j, target in enumerate(problem.targets):
        pin.framesForwardKinematics(problem.model, data, problem.configuration(q[j]))
        oMf = data.oMf[problem.frame_id]
        pos.append(float(np.linalg.norm(oMf.translation - target.position)))
        if target.rotation is not None:
            ang.append(float(np.linalg.norm(pin.log3(target.rotation.T @ oMf.rotation))))
        elif target.approach is not None:
            axis = oMf.rotation @ target.approach_axis
            sin = float(np.linalg.norm(np.cross(axis, target.approach)))
            ang.append(math.atan2(sin, float(axis @ target.approach)))
        else:
            ang.append(0.0)
    return np.array(pos), np.array(ang)


def _parse_3d(
    body: dict[str, Any], robot: RobotModel | pin.Model | None, source: Path
) -> tuple[IKPathResult, np.ndarray, np.ndarray]:
    model = _model_of(body, robot, source)
    name = model.name if isinstance(model, RobotModel) else str(model.name)
    clearance, legs = _clearance_of(body.get("clearance"), name, source.parent)
    if clearance is not None and not isinstance(model, RobotModel):
        raise ResultFileError(
            f"{source}: the path keeps clearance from a scene; pass robot= as a RobotModel "
            "(with its collision geometry), not a pinocchio.Model"
        )
    problem = CyclicIKProblem(
        robot=model,
        clearance=clearance,
        **legs,
        frame=str(body["frame"]),
        targets=tuple(_target(t) for t in body["targets"]),
        use_limits=bool(body["use_limits"]),
        q_lower=limits_from_json(body["q_lower"], -math.inf),
        q_upper=limits_from_json(body["q_upper"], math.inf),
        joint_weights=np.array(body["joint_weights"], dtype=float),
    )
    if list(problem.joint_names) != list(body["joint_names"]):
        raise ResultFileError(
            f"{source}: frame {problem.frame!r} is moved by joints {list(problem.joint_names)}, "
            f"the file lists {body['joint_names']}"
        )
    s = problem.n_targets
    q = problem.as_configurations(np.array(body["configurations"], dtype=float))
    history = history_from_json(body["history"], s, problem.n_joints)
    pos, ang = _fk_errors(problem, q)
    result = IKPathResult(
        problem=problem,
        method=str(body["method"]),
        status=SolveStatus(body["status"]),
        configurations=q.copy(),
        objective=problem.objective(q),
        position_errors=pos,
        orientation_errors=ang,
        limit_violation=problem.limit_violation(q),
        multipliers=np.array(body["multipliers"], dtype=float).reshape(s, -1),
        iterations=int(body["iterations"]),
        wall_time=float(body["wall_time"]),
        message=str(body["message"]),
        start=problem.as_configurations(np.array(body["start"], dtype=float), name="start"),
        history=history,
        # recomputed at the problem's margin, never the file's clearance_certificate
        clearance=(None if problem.clearance_rows is None else certify_path_clearance(problem, q)),
        clearance_multipliers=_clearance_multipliers_of(body, problem, source),
    )
    return (
        result,
        np.array(body["position_errors"], dtype=float),
        np.array(body["orientation_errors"], dtype=float),
    )


def _clearance_multipliers_of(
    body: dict[str, Any], problem: CyclicIKProblem, source: Path
) -> np.ndarray | None:
    """Read the file's clearance multipliers [rad^2/m]: one finite ``nu >= 0`` per row, or None.

    A file without them (or without a clearance) gives None; negative, non-finite
    (a JSON null reads as NaN) or non-numeric entries, a count other than the
    problem's rows, or multipliers of a problem without clearance are refused
    naming the key.
    """
    raw = body.get("clearance_multipliers")
    rows = problem.clearance_rows
    if raw is None:
        return None
    key = "clearance_multipliers"
    if rows is None:
        raise ResultFileError(f"{source}: {key} given for a problem without clearance")
    numbers = isinstance(raw, list) and all(
        v is None or (isinstance(v, int | float) and not isinstance(v, bool)) for v in raw
    )
    if not numbers:
        raise ResultFileError(f"{source}: {key} must be a list of numbers [rad^2/m]")
    nu = np.array([math.nan if v is None else v for v in raw], dtype=float)  # null: NaN
    if nu.shape != (len(rows.labels),):
        raise ResultFileError(
            f"{source}: {key} has {nu.size} entries, the problem has {len(rows.labels)} "
            "clearance rows"
        )
    bad = np.flatnonzero(~(np.isfinite(nu) & (nu >= 0.0)))
    if bad.size:
        i = int(bad[0])
        raise ResultFileError(
            f"{source}: {key}[{i}] = {float(nu[i]):g} ({rows.labels[i]}): a clearance multiplier "
            "must be finite and >= 0"
        )
    return nu


def _check_complementarity(source: Path, result: IKPathResult) -> None:
    """Refuse a claimed success whose clearance multipliers are > 0 on rows away from the margin.

    ``nu_i |g_i| <= COMPLEMENTARITY_TOL * max(1, E)`` with ``g`` recomputed from the
    configurations (the file's multipliers are data, not evidence).
    """
    nu = result.clearance_multipliers
    rows = result.problem.clearance_rows
    if nu is None or rows is None or not nu.size:
        return
    g = rows.rows(result.configurations.ravel()) - rows.spec.margin
    product = nu * np.abs(g)
    allowed = COMPLEMENTARITY_TOL * max(1.0, abs(result.objective))
    i = int(np.argmax(product))
    if product[i] > allowed:
        raise ResultFileError(
            f"{source}: clearance_multipliers[{i}] = {nu[i]:.6g} rad^2/m on row "
            f"{rows.labels[i]!r} at {g[i]:.3g} m from the margin: nu |g| = {product[i]:.3g} "
            f"> {allowed:.3g} rad^2 (not complementary)"
        )


def _load_3d(
    source: Path,
    body: dict[str, Any],
    robot: RobotModel | pin.Model | None,
    tols: tuple[float, float],
    margin: float,
) -> IKPathResult:
    """Read a 3-D result's body; target errors recomputed by ``pin.framesForwardKinematics``.

    A success claim is re-checked at each target's tolerance or the caller's
    ``tols`` (position [m], orientation [rad]), whichever is smaller, and
    against the model's joint limits (the file's may not be wider).
    """
    try:
        result, stored_pos, stored_ang = _parse_3d(body, robot, source)
        stored_e = float(body["objective"])
    except ResultFileError:
        raise
    except (KeyError, TypeError, ValueError, YoubotOptError) as exc:
        raise ResultFileError(f"{source}: incomplete or invalid IK-path result: {exc}") from exc
    bad = [
        f"{what} {j}: stored {a!r}, recomputed {b!r}"
        for what, stored, new in (
            ("position error [m] of target", stored_pos, result.position_errors),
            ("orientation error [rad] of target", stored_ang, result.orientation_errors),
        )
        for j, (a, b) in enumerate(zip(stored, new, strict=False))
        if not abs(a - b) <= RECHECK_TOL
    ]
    if stored_pos.shape != result.position_errors.shape:
        bad.append(
            f"{stored_pos.size} stored position errors for {result.problem.n_targets} targets"
        )
    if not abs(stored_e - result.objective) <= RECHECK_TOL:
        bad.append(f"E: stored {stored_e!r}, recomputed {result.objective!r} rad^2")
    if bad:
        raise ResultFileError(
            f"{source}: the stored figures disagree with pin.framesForwardKinematics on the "
            f"configurations (the file was edited or the robot changed): {'; '.join(bad[:4])}"
        )
    problem = result.problem
    if problem.use_limits and problem.q_lower is not None and problem.q_upper is not None:
        lower, upper = _model_limits(problem)
        wider = np.flatnonzero((problem.q_lower < lower) | (problem.q_upper > upper))
        if wider.size:
            names = [problem.joint_names[j] for j in wider]
            raise ResultFileError(
                f"{source}: the file's joint limits are wider than the model's for {names} "
                f"(file {problem.q_lower[wider].tolist()}..{problem.q_upper[wider].tolist()}, "
                f"model {lower[wider].tolist()}..{upper[wider].tolist()} rad or m)"
            )
    if result.success:
        pt = np.minimum([t.position_tol for t in problem.targets], tols[0])
        ot = np.minimum([t.orientation_tol for t in problem.targets], tols[1])
        missed = np.flatnonzero((result.position_errors > pt) | (result.orientation_errors > ot))
        if missed.size or result.limit_violation > 0.0:
            raise ResultFileError(
                f"{source}: claims {result.status.value!r} but targets {missed.tolist()} are "
                f"missed or the limits are violated by {result.limit_violation:.3g} rad"
            )
        callers = certify_path_clearance(problem, result.configurations, margin=margin)
        for whose, cert in (("its problem's", result.clearance), ("the caller's", callers)):
            if cert is not None and not cert.certified:
                a, b = cert.closest_pair
                raise ResultFileError(
                    f"{source}: claims {result.status.value!r} but its path does not keep "
                    f"{whose} clearance {cert.margin:g} m (coal): {a} / {b} at "
                    f"{cert.closest_distance:.4g} m, leg {int(cert.closest_time)}"
                )
        _check_complementarity(source, result)
    return result


def _model_limits(problem: CyclicIKProblem) -> tuple[np.ndarray, np.ndarray]:
    """Return the model's position limits [rad or m] of the problem's joints."""
    model = problem.model
    idx = [model.joints[model.getJointId(name)].idx_q for name in problem.joint_names]
    lower = np.asarray(model.lowerPositionLimit, dtype=float)[idx]
    upper = np.asarray(model.upperPositionLimit, dtype=float)[idx]
    return lower, upper


def _is_planar(result: IKPathResult) -> bool:
    """Whether ``result`` is written in the planar layout (a planar method's result)."""
    return result.constraint_tol is not None and result.problem.chain is not None


def encode_result(
    result: IKPathResult,
    robot: RobotSource | None = None,
    *,
    folder: str | os.PathLike[str] | None = None,
) -> bytes:
    """Return the file content :func:`save_result` writes for ``result`` (UTF-8 JSON).

    For writers that choose their own file name and write atomically (the
    multistart sweep stores); :func:`load_result` reads the bytes back from
    any file name.

    Parameters
    ----------
    result : IKPathResult
        The result (failed ones too).
    robot : RobotSource, optional
        How to load the robot again (3-D results; without it the loader needs
        ``robot=``). A planar method's result records its chain instead.
    folder : str or path-like, optional
        The folder the file goes to: the robot's URDF and package folders are
        recorded relative to it too (:meth:`RobotSource.to_json`).

    Returns
    -------
    bytes
        The JSON document with schema name, version, versions and checksum.
    """
    if _is_planar(result):
        return encode_document(SCHEMA, SCHEMA_VERSION, _planar_body(result))
    where = None if folder is None else Path(folder)
    return encode_document(SCHEMA, SCHEMA_VERSION, _body_3d(result, robot, where))


def save_result(
    result: IKPathResult, path: str | os.PathLike[str], robot: RobotSource | None = None
) -> Path:
    """Write ``result`` to ``path`` as JSON (``.json`` appended if missing), atomically.

    A planar method's result records its chain; any other records ``robot``
    (:meth:`RobotSource.of`; None: the loader will need ``robot=``) with its
    URDF's SHA-256 and its paths relative to the file's folder, so that the
    file still loads after the folder and the URDF moved together.

    Parameters
    ----------
    result : IKPathResult
        The result (failed ones too).
    path : str or path-like
        Target file; its folder must exist.
    robot : RobotSource, optional
        How to load the robot again (see above).

    Returns
    -------
    Path
        The file written.
    """
    return write_document(path, encode_result(result, robot, folder=Path(path).parent))


_SCHEMA_3D_0_1_0 = "youbot_opt.spatial_ikpath_result"  # 0.1.0's 3-D results: refused


def load_result(
    path: str | os.PathLike[str],
    *,
    robot: RobotModel | pin.Model | None = None,
    position_tol: float = DEFAULT_LOAD_POSITION_TOL,
    orientation_tol: float = DEFAULT_LOAD_ORIENTATION_TOL,
    margin: float = DEFAULT_LOAD_MARGIN,
) -> IKPathResult:
    """Read a result written by :func:`save_result` and check it against its robot.

    Parameters
    ----------
    path : str or path-like
        The JSON file.
    robot : RobotModel or pinocchio.Model, optional
        The robot of a 3-D result; default: loaded from the file's
        :class:`RobotSource`, its URDF taken from the recorded path or else
        from the recorded path relative to the file's folder, only with the
        recorded content (:meth:`RobotSource.load`). A planar result rebuilds
        its chain from the file.
    position_tol : float, optional
        The caller's largest position error [m] of a target (the library's
        default 1e-6 unless you pass another). A success claim is re-checked
        at the smaller of this and the file's tolerance of each target (a
        planar result: of its ``constraint_tol``): a file can only tighten it.
    orientation_tol : float, optional
        The caller's largest orientation error [rad] (as ``position_tol``).
    margin : float, optional
        The caller's clearance [m] of a path saved with a scene (default 0:
        no penetration): a success claim is re-checked with coal along the
        whole closed path (:func:`~youbot_opt.ikpath.clearance.certify_path_clearance`)
        against this margin, never the file's.

    Returns
    -------
    IKPathResult
        The result, with E, the target errors (Pinocchio) and the limit
        violation recomputed; a planar result's claimed success re-checked
        (:func:`~youbot_opt.ikpath.result.checked`).

    Raises
    ------
    ResultFileError
        If the file is missing or not JSON, of another schema or a newer
        version, written by 0.1.0 (the message names ``scripts/migrate_0_1_0.py``,
        which carries it forward), fails its checksum, is incomplete, its
        joint limits (with ``use_limits``) are wider than the model's, its robot cannot be loaded
        (the URDF not found: the message names the paths tried; or edited: it
        names the file and both SHA-256) or differs from the one it was solved
        on, its stored E or target errors disagree with the recomputed ones by
        more than 1e-9 (e.g. a moved target), or it claims a 3-D success that
        the recomputed errors, limits or clearance (``margin``) do not confirm.
    """
    source = Path(path)
    try:
        body = read_document(
            source,
            schema=SCHEMA,
            version=SCHEMA_VERSION,
            oldest=SCHEMA_VERSION,
            what="an IK-path result",
        )
    except ResultFileError:
        if _schema_of(source) == _SCHEMA_3D_0_1_0:
            raise ResultFileError(
                f"{source}: written by youbot_opt 0.1.0 (schema 1); run "
                f"`python {MIGRATION_SCRIPT} {source}` to carry it forward"
            ) from None
        raise
    tols = (
        _caller_tol(position_tol, "position_tol", "m"),
        _caller_tol(orientation_tol, "orientation_tol", "rad"),
    )
    if "chain" in body:
        return _load_planar(source, body, tols[0])
    ok = isinstance(margin, int | float) and not isinstance(margin, bool)
    if not (ok and 0.0 <= float(margin) < math.inf):
        raise ParameterError(
            f"margin must be a finite number >= 0 in [m], got {margin!r}",
            name="margin",
            value=margin,
        )
    return _load_3d(source, body, robot, tols, float(margin))


def _caller_tol(value: float, name: str, unit: str) -> float:
    """Return the caller's tolerance ``value`` as a float, or raise ParameterError."""
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not (ok and 0.0 < float(value) < math.inf):
        raise ParameterError(
            f"{name} must be a positive finite number in [{unit}], got {value!r}",
            name=name,
            value=value,
        )
    return float(value)


def _schema_of(source: Path) -> object:
    """Return the ``schema`` field of the JSON file ``source`` (None if unreadable)."""
    try:
        doc = json.loads(read_regular_file(source).decode("utf-8"))
    except (ResultFileError, UnicodeDecodeError, json.JSONDecodeError, RecursionError):
        return None
    return doc.get("schema") if isinstance(doc, dict) else None
