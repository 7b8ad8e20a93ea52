"""Save and load trajectory results: one ``.npz`` file with embedded JSON metadata.

Schema ``youbot_opt.trajopt_result`` (version :data:`SCHEMA_VERSION`): arrays
under ``"<group>__<name>"`` keys and a JSON ``"metadata"`` entry (versions,
problem, the robot's :class:`~youbot_opt.robot.source.RobotSource` so that it
reloads after a move, transcription, status, options, refinement record, SHA-256
of every array). Nothing is pickled, writes are atomic, and the loader re-checks
the result (:func:`youbot_opt.trajopt.check.checked`); :func:`load_refined`
re-runs the certificate of a plan saved as certified.

>>> result = load_result(save_result(result, "result.npz"))  # doctest: +SKIP
>>> result, refinement = load_refined(save_result(*refine(solver), "r.npz"))  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
import os
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
import pinocchio as pin

from youbot_opt._files import (
    array_digest,
    atomic_writer,
    check_schema_header,
    file_kind,
    read_npz,
    schema_header,
    software_versions,
)
from youbot_opt._typing import Array
from youbot_opt.collision.clearance import (
    clearance_document,
    clearance_from_document,
)
from youbot_opt.dynamics.numeric import batched_aba
from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.robot.catalogue import available_robots
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.payload import Payload
from youbot_opt.robot.source import RobotSource
from youbot_opt.trajopt.certify import Tolerances, certify
from youbot_opt.trajopt.check import checked
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.refine import Refined, Refinement, RefinementBudget, RefinementRound
from youbot_opt.trajopt.result import (
    DEFAULT_FEASIBILITY_TOL,
    SolveStats,
    SolveStatus,
    TrajOptResult,
)
from youbot_opt.trajopt.tool import tool_from_document
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.trajopt.transcription import get_transcription

__all__ = [
    "CHECKED_METHODS",
    "SCHEMA",
    "SCHEMA_VERSION",
    "load_refined",
    "load_result",
    "save_result",
]

SCHEMA = "youbot_opt.trajopt_result"
SCHEMA_VERSION = 2
_TRAJ_FIELDS = ("t", "q", "v", "a", "tau", "tau_mid", "v_stages", "a_stages", "tau_stages")
#: Transcriptions whose collocation rule the loader re-checks with ``pin.aba``
#: (:func:`youbot_opt.trajopt.check.check_result`); a file naming another is refused.
CHECKED_METHODS = ("trapezoidal", "hermite_simpson", "radau")


def _state(state: BoundaryState) -> dict[str, list[float]]:
    return {"q": state.q.tolist(), "v": state.velocity.tolist()}


_ROUND_ARRAYS = ("t", "errors", "objective_history")


def _refinement_meta(record: Refinement, arrays: dict[str, Array]) -> dict[str, Any]:
    """JSON of a refinement record; each round's grid and errors go to ``arrays``."""
    budget = {f.name: getattr(record.budget, f.name) for f in dataclasses.fields(record.budget)}
    tol = record.budget.tolerances
    budget["tolerances"] = None if tol is None else dataclasses.asdict(tol)
    rounds = []
    for r in record.rounds:
        row = {f.name: getattr(r, f.name) for f in dataclasses.fields(r)}
        for name in _ROUND_ARRAYS:
            arrays[f"refinement__{name}_{r.index}"] = np.asarray(row.pop(name), dtype=float)
        row["failures"] = list(r.failures)
        rounds.append(row)
    return {
        "certified": record.certified,
        "reason": record.reason,
        "elapsed": record.elapsed,
        "budget": budget,
        "rounds": rounds,
    }


def _refinement(meta: dict[str, Any] | None, arrays: dict[str, Array]) -> Refinement | None:
    """Rebuild the saved refinement record (certificate not attached), or None."""
    if meta is None:
        return None
    budget = dict(meta["budget"])
    tol = budget.pop("tolerances")
    rounds = []
    for row in meta["rounds"]:
        index = int(row["index"])
        values = {name: arrays[f"refinement__{name}_{index}"] for name in _ROUND_ARRAYS}
        for arr in values.values():
            arr.setflags(write=False)
        rounds.append(RefinementRound(**{**row, **values, "failures": tuple(row["failures"])}))
    return Refinement(
        certified=bool(meta["certified"]),
        reason=str(meta["reason"]),
        budget=RefinementBudget(**budget, tolerances=None if tol is None else Tolerances(**tol)),
        rounds=tuple(rounds),
        elapsed=float(meta["elapsed"]),
    )


def _recertify(result: TrajOptResult, record: Refinement, tolerances: Tolerances) -> Refined:
    """Certify again at the caller's ``tolerances``; downgrade a plan the certificate refutes.

    The file's own verdict and tolerances are reported (``record.budget`` keeps
    them), never used: a plan is certified on load only if it passes the
    independent check and :func:`certify` at ``tolerances``.
    """
    if not record.certified:
        return Refined(result, record)
    reason = ""
    cert = None
    if not result.success or result.trajectory is None:
        reason = f"not certified: the loaded result fails its check ({result.status.value})"
    else:
        cert = certify(result, tolerances=tolerances)
        if not cert.ok:
            failed = "; ".join(cert.failures())
            reason = f"not certified: the certificate re-run on load fails ({failed})"
    saved = record.budget.tolerances
    note = ""
    if saved is not None and saved != tolerances:
        note = (
            "certified again at the caller's tolerances, not the file's "
            f"({_differences(saved, tolerances)})"
        )
    if reason:
        reason = f"{reason}; {note}" if note else reason
        record = dataclasses.replace(record, certified=False, reason=reason, certificate=cert)
        message = f"{result.message}; {reason}"
    else:
        record = dataclasses.replace(record, certificate=cert)
        message = f"{result.message}; {note}" if note else result.message
    return Refined(dataclasses.replace(result, message=message), record)


def _differences(saved: Tolerances, used: Tolerances) -> str:
    """``name file X, used Y`` for each tolerance the file states differently."""
    a, b = dataclasses.asdict(saved), dataclasses.asdict(used)
    return ", ".join(f"{k}: file {a[k]:.3g}, used {b[k]:.3g}" for k in a if a[k] != b[k])


def _describe(problem: TrajOptProblem, folder: Path) -> dict[str, Any]:
    """Describe the problem, with its clearance (scene document, margin, pairs) if any."""
    desc = problem.describe()
    if problem.clearance is not None:
        desc["clearance"] = clearance_document(problem.clearance, folder)
    return desc


def save_result(
    result: TrajOptResult,
    path: str | os.PathLike[str],
    *,
    refinement: Refinement | None = None,
) -> Path:
    """Write ``result`` to ``path`` (``.npz`` appended if missing), atomically.

    Parameters
    ----------
    result : TrajOptResult
        The result to save (failed results too).
    path : str or path-like
        Target file; its directory must exist.
    refinement : Refinement, optional
        The record of the refinement that made ``result`` (:func:`refine
        <youbot_opt.trajopt.refine.refine>`), saved in the same file and read
        back by :func:`load_refined`.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ResultFileError
        If the directory does not exist or the file cannot be written.
    """
    target = Path(path)
    if target.suffix != ".npz":
        target = target.with_name(target.name + ".npz")
    if not target.parent.is_dir():
        raise ResultFileError(f"cannot save result: directory {target.parent} does not exist")
    arrays: dict[str, Array] = {"objective_history": np.asarray(result.objective_history)}
    if result.grid is not None:  # a non-uniform grid's interval fractions
        arrays["grid"] = np.asarray(result.grid, dtype=float)
    for group, values in (("variables", result.variables), ("multipliers", result.multipliers)):
        for name, arr in values.items():
            arrays[f"{group}__{name}"] = np.asarray(arr, dtype=float)
    for group, traj in (("trajectory", result.trajectory), ("guess", result.guess)):
        if traj is not None:
            for name in _TRAJ_FIELDS:
                value = getattr(traj, name)
                if value is not None:
                    arrays[f"{group}__{name}"] = np.asarray(value, dtype=float)
    record = None if refinement is None else _refinement_meta(refinement, arrays)
    meta: dict[str, Any] = {
        **schema_header(SCHEMA, SCHEMA_VERSION, software_versions(pin, ca, np)),
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "problem": _describe(result.problem, target.parent),
        "robot_source": _robot_source(result.problem.robot, target.parent),
        "payload": _payload_json(result.problem.robot),
        "method": result.method,
        "backend": result.backend,
        "status": result.status.value,
        "message": result.message,
        "solver_status": result.solver_status,
        "beta": result.beta,
        "bound_scale": result.bound_scale,
        "start": _state(result.start),
        "goal": _state(result.goal),
        "scalars": {
            k: float(getattr(result, k))
            for k in (
                "duration",
                "dt",
                "work",
                "objective",
                "wall_time",
                "cpu_time",
                "max_violation",
            )
        },
        "iterations": result.iterations,
        "options": result.options.to_dict(),
        "seed": result.seed,
        "feasibility_tol": float(result.feasibility_tol),
        "interpolation": {
            "trajectory": None if result.trajectory is None else result.trajectory.interpolation,
            "guess": None if result.guess is None else result.guess.interpolation,
        },
        "refinement": record,
        "checksums": {key: array_digest(arr) for key, arr in arrays.items()},
    }
    payload = json.dumps(meta, allow_nan=True, sort_keys=True).encode("utf-8")
    arrays["metadata"] = np.frombuffer(payload, dtype=np.uint8)
    try:
        with atomic_writer(target) as handle:
            np.savez_compressed(handle, **arrays)  # type: ignore[arg-type]
    except OSError as exc:
        raise ResultFileError(f"cannot write result file {target}: {exc}") from exc
    return target


def _read(path: Path) -> tuple[dict[str, Any], dict[str, Array]]:
    """Metadata and checksum-verified arrays of a result file."""
    if not path.is_file():
        if not path.exists():
            raise ResultFileError(f"result file {path} does not exist")
        kind = file_kind(path.stat().st_mode)
        raise ResultFileError(f"result file {path} is not a regular file ({kind}); not opened")
    arrays = read_npz(path)
    if "metadata" not in arrays:
        raise ResultFileError(f"{path} has no metadata entry; not a youbot_opt result file")
    try:
        meta = json.loads(arrays.pop("metadata").tobytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ResultFileError(f"{path}: metadata is not valid JSON (corrupted file)") from exc
    check_schema_header(
        meta, schema=SCHEMA, supported=SCHEMA_VERSION, oldest=SCHEMA_VERSION, source=str(path)
    )
    checksums = meta.get("checksums", {})
    if not isinstance(checksums, dict) or set(checksums) != set(arrays):
        raise ResultFileError(f"{path}: arrays do not match the metadata's list (corrupted file)")
    for key, arr in arrays.items():
        if array_digest(arr) != checksums[key]:
            raise ResultFileError(f"{path}: checksum mismatch in array {key!r} (corrupted file)")
    return meta, arrays


def _group(arrays: dict[str, Array], group: str) -> dict[str, Array]:
    prefix = f"{group}__"
    return {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)}


def _trajectory(values: dict[str, Array], interpolation: str | None) -> Trajectory | None:
    if interpolation is None or not values:
        return None
    return Trajectory(
        **{name: values.get(name) for name in _TRAJ_FIELDS},  # type: ignore[arg-type]
        interpolation=interpolation,  # type: ignore[arg-type]
    )


def _robot_source(robot: RobotModel, folder: Path) -> dict[str, Any] | None:
    """How to load ``robot`` again from a file in ``folder``; None if built in memory."""
    try:
        return RobotSource.of(robot).to_json(folder=folder)
    except ParameterError:  # no file and no known name, or the URDF is unreadable now
        return None


def _payload_json(robot: RobotModel) -> dict[str, Any] | None:
    """Return the payload the robot carries as JSON (its source has it too, if it has one)."""
    return None if robot.payload is None else robot.payload.to_json()


def _robot(desc: dict[str, Any], source: dict[str, Any] | None, path: Path) -> RobotModel:
    """Load the robot a result was solved on again, with the saved joint damping."""
    name = desc["robot"]
    if source is not None:
        spec = RobotSource.from_json(source)
    else:  # a robot built in memory: by its name or URDF path, no options
        old = name if name in available_robots() else desc.get("urdf_path")
        if old is None:
            raise ResultFileError(f"cannot reload robot {name!r}: no URDF path saved; pass robot=")
        payload = None if desc.get("payload") is None else Payload.from_json(desc["payload"])
        spec = RobotSource(source=str(old), payload=payload)
    where = spec.source
    try:
        robot = spec.load(folder=path.parent)
    except YoubotOptError as exc:
        raise ResultFileError(
            f"{path}: cannot reload robot {name!r} from {where}: {exc}; pass robot= (the "
            "RobotModel to attach, e.g. load_model(...) of an edited URDF if the change "
            "is intended)"
        ) from exc
    damping = np.asarray(desc.get("model_damping", []), dtype=float)
    if damping.shape == (robot.nv,):
        robot.model.damping = damping
    return robot


def load_result(
    path: str | os.PathLike[str],
    *,
    robot: RobotModel | None = None,
    feasibility_tol: float = DEFAULT_FEASIBILITY_TOL,
) -> TrajOptResult:
    """Read the result written by :func:`save_result` (:func:`load_refined`: with its record).

    Parameters
    ----------
    path : str or path-like
        The ``.npz`` file.
    robot : RobotModel, optional
        The robot to attach (it overrides everything the file says of its
        robot). When omitted, reloaded from the saved
        :class:`~youbot_opt.robot.source.RobotSource` ``"robot_source"``: the
        robot name, or the URDF at its saved absolute path, else at its saved
        path relative to this file's folder, only with the saved SHA-256 of
        its content; with the saved package folders, locked joints and
        strictness, and the saved joint damping. A robot built in memory (no
        source saved) reloads from the name or URDF path of ``"problem"``.
    feasibility_tol : float, optional
        Largest violation [rad, rad/s, N m, s] accepted by the check on load
        (the library's default unless you pass another). The file's own
        tolerance is never used: the loaded result carries this one, and the
        message names the file's when it differs.

    Returns
    -------
    TrajOptResult
        The result, with its problem rebuilt from the reloaded model; a saved
        success claim that the independent check
        (:func:`youbot_opt.trajopt.check.checked`: bounds from the model, the
        collocation rule with ``pin.aba``, the reported figures from the
        variables) refutes at ``feasibility_tol`` is downgraded.

    Raises
    ------
    ResultFileError
        If the file is missing, corrupted (bad zip, bad JSON, checksum
        mismatch), of another schema or of another schema version (one written
        by 0.1.0: the message names ``scripts/migrate_0_1_0.py``), names a
        transcription the loader cannot check (not one of
        :data:`CHECKED_METHODS`), or its robot cannot be reloaded (the URDF
        not found: the message names the paths tried; or edited: it names the
        file and both SHA-256).
    ParameterError
        If ``feasibility_tol`` is not a positive finite number.
    """
    return _load(Path(path), robot, feasibility_tol)[0]


def load_refined(
    path: str | os.PathLike[str],
    *,
    robot: RobotModel | None = None,
    feasibility_tol: float = DEFAULT_FEASIBILITY_TOL,
    tolerances: Tolerances | None = None,
) -> Refined:
    """Read a refined result and its refinement record written by :func:`save_result`.

    Parameters
    ----------
    path : str or path-like
        The ``.npz`` file, saved with ``refinement=``.
    robot : RobotModel, optional
        The robot to attach (as :func:`load_result`).
    feasibility_tol : float, optional
        As :func:`load_result`.
    tolerances : Tolerances, optional
        The certificate's thresholds on load; ``Tolerances()`` (the library's
        defaults) unless you pass others. The file's own tolerances are kept
        in ``refinement.budget`` and reported, never used.

    Returns
    -------
    Refined
        The result (as :func:`load_result` returns it) and its refinement record
        (rounds, budget, verdict). A plan saved as certified is certified again
        only if it passes the independent check and
        :func:`~youbot_opt.trajopt.certify.certify`, re-run here at
        ``tolerances`` (a forward simulation; the certificate is attached as
        ``refinement.certificate``); otherwise ``refinement.certified`` is
        False and ``refinement.reason`` (also appended to the message) says why.

    Raises
    ------
    ResultFileError
        As :func:`load_result`, and if the file holds no refinement record.
    """
    path = Path(path)
    if tolerances is not None and not isinstance(tolerances, Tolerances):
        raise ParameterError(
            f"tolerances must be a Tolerances, got {type(tolerances).__name__}",
            name="tolerances",
        )
    result, record = _load(path, robot, feasibility_tol)
    if record is None:
        raise ResultFileError(
            f"{path} holds no refinement record (a fixed-grid result): use load_result"
        )
    return _recertify(result, record, Tolerances() if tolerances is None else tolerances)


def _load(
    path: Path, robot: RobotModel | None, feasibility_tol: float
) -> tuple[TrajOptResult, Refinement | None]:
    """Return the checked result of a file and its refinement record (not re-certified)."""
    tol = float(feasibility_tol) if isinstance(feasibility_tol, (int, float)) else math.nan
    if isinstance(feasibility_tol, bool) or not (0.0 < tol < math.inf):
        raise ParameterError(
            f"feasibility_tol must be a positive finite number, got {feasibility_tol!r}",
            name="feasibility_tol",
            value=feasibility_tol,
        )
    meta, arrays = _read(path)
    method = meta.get("method")
    if method not in CHECKED_METHODS:
        raise ResultFileError(
            f"{path}: transcription {method!r} cannot be checked on load (the loader re-checks "
            f"the collocation rules of {', '.join(CHECKED_METHODS)} only); a result it cannot "
            "check is not read"
        )
    try:
        desc = meta["problem"]
        if robot is None:
            robot = _robot({**desc, "payload": meta.get("payload")}, meta["robot_source"], path)
        problem = TrajOptProblem(
            robot=robot,
            start=BoundaryState(q=desc["start_q"], v=desc["start_v"]),
            goal=BoundaryState(q=desc["goal_q"], v=desc["goal_v"]),
            n_knots=int(desc["n_knots"]),
            duration=desc["duration"],
            scaled_bounds=tuple(desc["scaled_bounds"]),
            dt_min=desc["dt_min"],
            dt_max=np.inf if desc["dt_max"] is None else desc["dt_max"],
            damping=bool(desc["damping"]),
            clearance=None
            if desc.get("clearance") is None
            else clearance_from_document(
                desc["clearance"], str(robot.name), path.absolute().parent
            ),
            tool=tuple(tool_from_document(d) for d in desc.get("tool", ())),
        )
        opts = dict(meta["options"])
        scalars = meta["scalars"]
        variables = _group(arrays, "variables")
        multipliers = _group(arrays, "multipliers")
        for arr in (*variables.values(), *multipliers.values()):
            arr.setflags(write=False)
        history = arrays["objective_history"]
        history.setflags(write=False)
        result = TrajOptResult(
            problem=problem,
            method=meta["method"],
            backend=meta["backend"],
            status=SolveStatus(meta["status"]),
            message=meta["message"],
            trajectory=_trajectory(
                _group(arrays, "trajectory"), meta["interpolation"]["trajectory"]
            ),
            variables=variables,
            duration=scalars["duration"],
            dt=scalars["dt"],
            work=scalars["work"],
            objective=scalars["objective"],
            beta=float(meta["beta"]),
            bound_scale=float(meta["bound_scale"]),
            start=BoundaryState(q=meta["start"]["q"], v=meta["start"]["v"]),
            goal=BoundaryState(q=meta["goal"]["q"], v=meta["goal"]["v"]),
            stats=SolveStats(
                solver_status=meta["solver_status"],
                iterations=int(meta["iterations"]),
                wall_time=scalars["wall_time"],
                cpu_time=scalars["cpu_time"],
                objective_history=history,
            ),
            max_violation=scalars["max_violation"],
            multipliers=multipliers,
            guess=_trajectory(_group(arrays, "guess"), meta["interpolation"]["guess"]),
            options=IpoptOptions(**opts),
            seed=meta["seed"],
            feasibility_tol=tol,
            grid=arrays.get("grid"),
        )
        saved_tol = float(meta["feasibility_tol"])
        result, rebuilt = _with_rebuilt_trajectory(result)
        record = _refinement(meta.get("refinement"), arrays)
    except ResultFileError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ResultFileError(f"{path}: malformed result metadata ({exc!r})") from exc
    # A file is data from outside: the independent check, at the caller's tolerance and
    # the model's bounds, sets the status it deserves (load_refined certifies again).
    try:
        result = checked(result)
    except (TypeError, ValueError, KeyError) as exc:  # a figure of the wrong type
        raise ResultFileError(f"{path}: malformed result metadata ({exc!r})") from exc
    notes = [rebuilt] if rebuilt else []
    if saved_tol != tol:
        notes.append(f"checked at feasibility_tol = {tol:.3g}, not the file's {saved_tol:.3g}")
    if notes:
        result = dataclasses.replace(result, message="; ".join([result.message, *notes]))
    return result, record


def _with_rebuilt_trajectory(result: TrajOptResult) -> tuple[TrajOptResult, str]:
    """Rebuild the trajectory from the variables; note it when the file's differed.

    The trajectory (what the certificate simulates and the replay shows) is
    derived data: rebuilt here with the transcription's own interpolation and
    ``pin.aba`` accelerations, so that a file cannot certify a motion its
    variables do not describe. A saved trajectory that agrees with the rebuilt
    one to 1e-9 (absolute and relative: the solver's CasADi accelerations and
    ``pin.aba`` differ by rounding only, about 1e-13 relative) is kept as saved,
    so that a round trip is exact.
    """
    problem, v = result.problem, result.variables
    try:
        dt = float(np.asarray(v["dt"]).ravel()[0])
        arrays = [np.asarray(x, dtype=float) for x in v.values()]
    except (KeyError, IndexError, TypeError, ValueError):
        return result, ""  # malformed: the check reports it
    if not (dt > 0.0 and all(np.all(np.isfinite(x)) for x in arrays)):
        return result, ""
    method = get_transcription(result.method)
    if result.grid is not None:
        method = method.with_fractions(result.grid)
    aba = batched_aba(problem.robot, damping=problem.damping)

    def accel(q: Array, qd: Array, tau: Array) -> Array:
        return np.asarray(aba(q, qd, tau), dtype=float).reshape(np.shape(qd))

    try:
        values = {k: np.asarray(x, dtype=float) for k, x in v.items()}
        traj = method.trajectory(values, accel(values["q"], values["v"], values["tau"]), accel)
    except (KeyError, TypeError, ValueError):
        return result, ""  # malformed: the check reports it
    old = result.trajectory
    same = old is not None and all(
        getattr(old, name) is None
        if getattr(traj, name) is None
        else getattr(old, name) is not None
        and np.shape(getattr(old, name)) == np.shape(getattr(traj, name))
        and np.allclose(getattr(old, name), getattr(traj, name), rtol=1e-9, atol=1e-9)
        for name in _TRAJ_FIELDS
    )
    if same:  # the saved one (the solver's CasADi accelerations) agrees to rounding: keep it
        return result, ""
    note = "the file's trajectory differs from its variables: rebuilt from them"
    return dataclasses.replace(result, trajectory=traj), note
