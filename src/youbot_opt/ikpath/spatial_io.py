"""Save and load spatial IK-path results: one JSON file with schema, version and checksum.

Schema ``youbot_opt.spatial_ikpath_result`` (version :data:`SCHEMA_VERSION`):
the robot's source (:class:`~youbot_opt.robot.source.RobotSource`: a name, or a
URDF by path, path relative to the file and SHA-256, and the loading options,
so that the file reloads on its own, also after a move), a fingerprint of its
kinematics, the frame, targets, limits, configurations, reported errors and
history under ``"result"``, its SHA-256 under ``"sha256"``. Loading rebuilds
the problem, recomputes every target's errors by ``pin.framesForwardKinematics``
and ``E``, and refuses a file whose stored figures disagree (a moved target, a
changed robot) or whose claimed success the check does not confirm.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from youbot_opt._files import array_digest
from youbot_opt.exceptions import ResultFileError, YoubotOptError
from youbot_opt.ikpath.io import (
    RECHECK_TOL,
    encode_document,
    history_from_json,
    history_to_json,
    limits_from_json,
    limits_to_json,
    read_document,
    write_document,
)
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKPathResult
from youbot_opt.ikpath.targets import Target, quaternion_to_matrix
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.source import RobotSource

__all__ = [
    "SCHEMA",
    "SCHEMA_VERSION",
    "RobotSource",
    "encode_spatial_result",
    "load_spatial_result",
    "save_spatial_result",
    "spatial_problem_spec",
]

SCHEMA = "youbot_opt.spatial_ikpath_result"
SCHEMA_VERSION = 1


def _kinematics_digest(model: pin.Model) -> str:
    """SHA-256 of the joint placements and position limits (what the kinematics depend on)."""
    placements = np.array([m.homogeneous for m in model.jointPlacements], dtype=float)
    frames = np.array([f.placement.homogeneous for f in model.frames], dtype=float)
    limits = np.stack([model.lowerPositionLimit, model.upperPositionLimit])
    return array_digest(np.concatenate([placements.ravel(), frames.ravel(), limits.ravel()]))


def spatial_problem_spec(problem: CyclicIKProblem) -> dict[str, Any]:
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


def _body(result: IKPathResult, robot: RobotSource | None, folder: Path | None) -> dict[str, Any]:
    return {
        "robot": None if robot is None else robot.to_json(folder=folder),
        **spatial_problem_spec(result.problem),
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
    }


def encode_spatial_result(
    result: IKPathResult,
    robot: RobotSource | None = None,
    *,
    folder: str | os.PathLike[str] | None = None,
) -> bytes:
    """Return the file content :func:`save_spatial_result` writes (UTF-8 JSON).

    Parameters
    ----------
    result : IKPathResult
        The result (failed ones too).
    robot : RobotSource, optional
        How to load the robot again; without it the loader needs ``robot=``.
    folder : str or path-like, optional
        The folder the file goes to: the robot's URDF and package folders are
        recorded relative to it too (:meth:`RobotSource.to_json`).
    """
    where = None if folder is None else Path(folder)
    return encode_document(SCHEMA, SCHEMA_VERSION, _body(result, robot, where))


def save_spatial_result(
    result: IKPathResult, path: str | os.PathLike[str], robot: RobotSource | None = None
) -> Path:
    """Write ``result`` to ``path`` as JSON (``.json`` appended if missing), atomically.

    ``robot`` (:meth:`RobotSource.of`; None: the loader will need ``robot=``)
    is written with its URDF's SHA-256 and its paths relative to the file's
    folder, so that the file still loads after the folder and the URDF moved
    together.

    Returns
    -------
    Path
        The file written.
    """
    folder = Path(path).parent
    return write_document(path, encode_spatial_result(result, robot, folder=folder))


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
) -> pin.Model:
    """Return the caller's model, else the file's robot source loaded; check its fingerprint."""
    if robot is None:
        spec = body.get("robot")
        if spec is None:
            raise ResultFileError(
                f"{source}: the file names no robot source; pass robot= (the RobotModel or "
                "pinocchio.Model it was solved on)"
            )
        try:
            model = RobotSource.from_json(spec).load(folder=source.parent).model
        except YoubotOptError as exc:
            raise ResultFileError(
                f"{source}: cannot load the robot it was solved on: {exc}; pass robot= (the "
                "RobotModel to check it against, e.g. load_model(...) of an edited URDF if "
                "the change is intended)"
            ) from exc
    else:
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
    return model


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


def _parse(
    body: dict[str, Any], robot: RobotModel | pin.Model | None, source: Path
) -> tuple[IKPathResult, np.ndarray, np.ndarray]:
    model = _model_of(body, robot, source)
    problem = CyclicIKProblem(
        robot=model,
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
    )
    return (
        result,
        np.array(body["position_errors"], dtype=float),
        np.array(body["orientation_errors"], dtype=float),
    )


def load_spatial_result(
    path: str | os.PathLike[str], *, robot: RobotModel | pin.Model | None = None
) -> IKPathResult:
    """Read a result written by :func:`save_spatial_result` and check it against the robot.

    Parameters
    ----------
    path : str or path-like
        The JSON file (a run folder's ``result.json``).
    robot : RobotModel or pinocchio.Model, optional
        The robot; default: loaded from the file's :class:`RobotSource`, its
        URDF taken from the recorded path or else from the recorded path
        relative to the file's folder, only with the recorded content
        (:meth:`RobotSource.load`).

    Returns
    -------
    IKPathResult
        The result, with ``E``, the target errors (``pin.framesForwardKinematics``)
        and the limit violation recomputed.

    Raises
    ------
    ResultFileError
        If the file is missing or not JSON, of another schema or a newer
        version, fails its checksum, is incomplete, its robot cannot be loaded
        (the URDF not found: the message names the paths tried; or edited: it
        names the file and both SHA-256) or differs from the one it was solved
        on, its stored E or target errors disagree with the recomputed ones by
        more than 1e-9 (e.g. a moved target), or it claims a
        success that the recomputed errors or limits do not confirm.
    """
    source = Path(path)
    body = read_document(
        source, schema=SCHEMA, version=SCHEMA_VERSION, what="a spatial IK-path result"
    )
    try:
        result, stored_pos, stored_ang = _parse(body, robot, source)
        stored_e = float(body["objective"])
    except ResultFileError:
        raise
    except (KeyError, TypeError, ValueError, YoubotOptError) as exc:
        raise ResultFileError(
            f"{source}: incomplete or invalid spatial IK-path result: {exc}"
        ) from exc
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
    if result.success:
        pt = np.array([t.position_tol for t in result.problem.targets])
        ot = np.array([t.orientation_tol for t in result.problem.targets])
        missed = np.flatnonzero((result.position_errors > pt) | (result.orientation_errors > ot))
        if missed.size or result.limit_violation > 0.0:
            raise ResultFileError(
                f"{source}: claims {result.status.value!r} but targets {missed.tolist()} are "
                f"missed or the limits are violated by {result.limit_violation:.3g} rad"
            )
    return result
