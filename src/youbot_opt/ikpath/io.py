"""Save and load IK-path results: one JSON file with a schema name, version and checksum.

Schema ``youbot_opt.ikpath_result`` (version :data:`SCHEMA_VERSION`): the
chain, targets, configurations, reported figures and history under
``"result"``, its SHA-256 under ``"sha256"``. Writes are atomic. Loading
rebuilds the problem, recomputes E, residuals and limit violation, refuses a
corrupt or newer file, and re-checks a claimed success
(:func:`~youbot_opt.ikpath.result.build_result`; layout: docs/design.md, "Module notes").
The document helpers (header, checksum, history, limits) serve :mod:`.spatial_io` too.

>>> load_ikpath_result(save_ikpath_result(result, "path.json")).objective  # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from youbot_opt._files import (
    atomic_write_bytes,
    check_schema_header,
    json_digest,
    schema_header,
    software_versions,
)
from youbot_opt.exceptions import ResultFileError, YoubotOptError
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKPathResult, OuterIterate, build_result
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.planar import PlanarChain

__all__ = [
    "RECHECK_TOL",
    "SCHEMA",
    "SCHEMA_VERSION",
    "encode_document",
    "encode_ikpath_result",
    "finite_or_none",
    "history_from_json",
    "history_to_json",
    "limits_from_json",
    "limits_to_json",
    "load_ikpath_result",
    "problem_spec",
    "read_document",
    "save_ikpath_result",
    "write_document",
]

SCHEMA = "youbot_opt.ikpath_result"
SCHEMA_VERSION = 1
RECHECK_TOL = 1e-9
"""Largest accepted ``|stored - recomputed|`` of E [rad^2] and of the residuals or target
errors [m, rad] of an IK-path file: both come from the same float64 formulas, which agree
across CPUs to ~1e-15; a target moved by more than 1e-9 m (or a changed robot) is detected."""


def finite_or_none(x: float) -> float | None:
    """``float(x)``, or ``None`` (JSON ``null``) for an infinite or NaN ``x``."""
    return float(x) if math.isfinite(x) else None


def limits_to_json(values: Iterable[float]) -> list[float | None]:
    """JSON form of joint limits in [rad] or [m]: ``null`` for an infinite (absent) limit."""
    return [finite_or_none(v) for v in values]


def limits_from_json(values: Iterable[float | None], fill: float) -> np.ndarray:
    """Inverse of :func:`limits_to_json`: ``null`` becomes ``fill`` (``-inf`` or ``inf``)."""
    return np.array([fill if v is None else float(v) for v in values], dtype=float)


def history_to_json(history: Iterable[OuterIterate]) -> list[dict[str, Any]]:
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
    items: Iterable[dict[str, Any]], n_targets: int, n_joints: int
) -> tuple[OuterIterate, ...]:
    """Inverse of :func:`history_to_json`; each iterate's ``x`` shaped (n_targets, n_joints).

    Raises
    ------
    KeyError, TypeError, ValueError
        For a missing field or a value of the wrong shape or type.
    """

    def num(value: Any) -> float:
        return math.nan if value is None else float(value)

    return tuple(
        OuterIterate(
            int(h["iteration"]),
            np.array(h["x"], dtype=float).reshape(n_targets, n_joints),
            num(h["objective"]),
            num(h["violation"]),
            num(h["stationarity"]),
            num(h["penalty"]),
            int(h["inner_iterations"]),
        )
        for h in items
    )


def encode_document(schema: str, version: int, body: dict[str, Any]) -> bytes:
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
    path: str | os.PathLike[str], *, schema: str, version: int, what: str
) -> dict[str, Any]:
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

    Raises
    ------
    ResultFileError
        If the file is missing or not JSON, of another schema, of a newer (or
        invalid) schema version, or fails its checksum.
    """
    source = Path(path)
    try:
        doc = json.loads(source.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ResultFileError(f"{source}: cannot read {what}: {exc}") from exc
    check_schema_header(doc, schema=schema, supported=version, source=str(source))
    body = doc.get("result")
    if not isinstance(body, dict) or doc.get("sha256") != json_digest(body):
        raise ResultFileError(f"{source}: checksum mismatch; the file is corrupt")
    return body


def problem_spec(problem: CyclicIKProblem) -> dict[str, Any]:
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


def _body(result: IKPathResult) -> dict[str, Any]:
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


def encode_ikpath_result(result: IKPathResult) -> bytes:
    """Return the file content :func:`save_ikpath_result` writes for ``result`` (UTF-8 JSON).

    For writers that choose their own file name and write atomically (the
    multistart sweep store); :func:`load_ikpath_result` reads the bytes back
    from any file name.

    Parameters
    ----------
    result : IKPathResult
        The result (failed ones too).

    Returns
    -------
    bytes
        The JSON document with schema name, version, versions and checksum.
    """
    return encode_document(SCHEMA, SCHEMA_VERSION, _body(result))


def save_ikpath_result(result: IKPathResult, path: str | os.PathLike[str]) -> Path:
    """Write ``result`` to ``path`` as JSON (``.json`` appended if missing), atomically.

    Parameters
    ----------
    result : IKPathResult
        The result (failed ones too).
    path : str or path-like
        Target file; its folder must exist.

    Returns
    -------
    Path
        The file written.
    """
    return write_document(path, encode_ikpath_result(result))


def _parse(body: dict[str, Any]) -> IKPathResult:
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
        status=SolveStatus(body["status"]),  # also the values of IKStatus ("success", ...)
        x=np.array(body["configurations"], dtype=float),
        multipliers=np.array(body["multipliers"], dtype=float),
        iterations=int(body["iterations"]),
        inner_iterations=int(body["inner_iterations"]),
        wall_time=float(body["wall_time"]),
        message=str(body["message"]),
        start=np.array(body["start"], dtype=float),
        constraint_tol=float(body.get("constraint_tol", _default_tol(str(body["method"])))),
        history=history,
    )


def _default_tol(method: str) -> float:
    """Default ``|c_i|`` tolerance in [m] of ``method`` (files without ``constraint_tol``)."""
    from youbot_opt.ikpath.methods.al import ALOptions

    if method == "ipopt":
        return float(IpoptOptions.for_ikpath().constr_viol_tol)  # type: ignore[arg-type]
    return ALOptions().constraint_tol


def load_ikpath_result(path: str | os.PathLike[str]) -> IKPathResult:
    """Read a result written by :func:`save_ikpath_result`.

    Parameters
    ----------
    path : str or path-like
        The JSON file.

    Returns
    -------
    IKPathResult
        The result; E, residuals and limit violation recomputed (Pinocchio),
        and a claimed success re-checked (:func:`~youbot_opt.ikpath.result.checked`):
        the status is the one the check gives it.

    Raises
    ------
    ResultFileError
        If the file is missing or not JSON, of another schema, of a newer (or
        invalid) schema version, fails its checksum, is incomplete, or its
        stored E / residuals disagree with the recomputed ones by more than 1e-9.
    """
    source = Path(path)
    body = read_document(source, schema=SCHEMA, version=SCHEMA_VERSION, what="an IK-path result")
    try:
        result = _parse(body)
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
