"""The on-disk store of a trajectory sweep: its identity and its payloads (spec ``trajopt.md``).

Owns :func:`result_codec` (the :class:`~youbot_opt.sweeps.store.Codec` of a
sweep whose payloads are :mod:`youbot_opt.trajopt.io` result files) and what its
manifest records: :func:`sweep_params` (problem, method, backend, options) with the robot
named by :func:`robot_identity`, the SHA-256 of its URDF's content, so a store
resumes wherever the output folder, the URDF or the package now lie.

    params = {**sweep_params(solver), "seed": 0}
    store = open_store("runs/ms", "multistart", params, result_codec(solver))
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from youbot_opt._files import MIGRATION_SCRIPT
from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.source import urdf_digest
from youbot_opt.sweeps.store import SCHEMA_VERSION, Codec
from youbot_opt.trajopt.optimality import first_order
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver

__all__ = [
    "ItemMaking",
    "check_item",
    "jobs_making",
    "result_codec",
    "robot_identity",
    "sweep_params",
]

ItemMaking = Callable[[str], Mapping[str, float | int | None]]
"""``key -> {"beta": ..., "bound_scale": ..., "seed": ...}``: what makes item ``key`` of a
sweep (``"seed"`` only where the item is a seeded start); ``KeyError``: no such item."""

OBJECTIVE_RTOL = 1e-9
"""Relative tolerance of a stored item's objective re-evaluated at its sweep's beta
(summation order only: the loader has checked duration and work against the variables)."""


def result_codec(solver: TrajOptSolver, made_by: ItemMaking | None = None) -> Codec[TrajOptResult]:
    """Return how a trajectory sweep's payloads are stored: :mod:`youbot_opt.trajopt.io` files.

    Its robot loads the stored results. A store written by 0.1.0 (its problem
    holds a ``"beta"`` or the URDF's absolute ``"urdf_path"``) is refused:
    ``scripts/migrate_0_1_0.py`` carries it forward.

    With ``made_by`` every payload read back is re-checked against the sweep's
    own problem (:func:`check_item`): the solver's problem, method and robot,
    the item's beta, bound scale and start seed, its objective re-evaluated
    at the sweep's beta, and a success's first-order optimality at that beta;
    an item copied from another sweep is refused and recomputed, whatever its
    checksums say.
    """
    from youbot_opt.trajopt.io import load_result, save_result

    return Codec(
        save=save_result,
        load=functools.partial(load_result, robot=solver.problem.robot),
        suffix=".npz",
        refuse_old=_refuse_0_1_0,
        check=None if made_by is None else functools.partial(check_item, solver, made_by),
    )


def jobs_making(jobs: Any) -> ItemMaking:
    """Return what makes each item of start jobs (``jobs.job(key)``): beta, bound scale, seed."""
    return functools.partial(_job_making, jobs)


def _job_making(jobs: Any, key: str) -> dict[str, float | int | None]:
    job = jobs.job(key)
    return {"beta": job.beta, "bound_scale": job.bound_scale, "seed": job.seed}


def _problem(result_or_solver: TrajOptResult | TrajOptSolver) -> dict[str, Any]:
    desc = result_or_solver.problem.describe()
    desc.pop("urdf_path", None)
    return json.loads(json.dumps(desc, allow_nan=True))


def check_item(
    solver: TrajOptSolver, made_by: ItemMaking, key: str, result: TrajOptResult
) -> str | None:
    """Why ``result``, read back as item ``key``, is not that item of the sweep (``None``: it is).

    Compared with what makes the item (``made_by(key)``) and the sweep's
    solver: the problem (boundary states, knots, bounds, clearance, robot
    digest), the transcription, beta, the bound scale, the start's seed, and
    the objective ``beta T + (1 - beta) W`` at the sweep's beta (relative
    :data:`OBJECTIVE_RTOL`). A success must moreover be a first-order optimum
    of the sweep's NLP at the sweep's beta and bound scale
    (:func:`youbot_opt.trajopt.optimality.first_order`: the KKT conditions with
    the file's multipliers checked, never trusted), so a plan optimal for
    another beta, its beta and objective edited to agree, is refused.
    """
    try:
        made = made_by(key)
    except KeyError:
        return f"{key!r} is no item of this sweep"
    if result.method != solver.method.name:
        return f"transcription {result.method!r}, the sweep's is {solver.method.name!r}"
    if result.problem.robot is not solver.problem.robot:
        return "another robot"
    mine, theirs = _problem(solver), _problem(result)
    if mine != theirs:
        fields = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
        return f"its problem differs in {', '.join(fields)}"
    for name in ("beta", "bound_scale", "seed"):
        if name in made and getattr(result, name) != made[name]:
            return f"{name} = {getattr(result, name)!r}, the item's is {made[name]!r}"
    beta = float(made.get("beta", result.beta) or 0.0)
    value = beta * result.duration + (1.0 - beta) * result.work
    if not (math.isfinite(value) and math.isfinite(result.objective)):
        return "a success with a non-finite objective" if result.success else None
    if not abs(result.objective - value) <= OBJECTIVE_RTOL * max(1.0, abs(value)):
        return (
            f"objective {result.objective:.9g}, but at the sweep's beta = {beta:g} its "
            f"trajectory gives {value:.9g}"
        )
    if not result.success:
        return None  # no optimality claimed: a failed start is never a sweep's optimum
    scale = made.get("bound_scale")
    try:
        report = first_order(
            solver, result, beta=beta, bound_scale=result.bound_scale if scale is None else scale
        )
    except ParameterError as exc:
        return f"a success that cannot be checked: {exc}"
    if not report.passed:
        return f"it is no first-order optimum of the sweep's problem at beta = {beta:g}: " + str(
            report.reason
        )
    return None


def robot_identity(robot: RobotModel) -> str | None:
    """Return the SHA-256 (hex) of the URDF file ``robot`` was loaded from (``None``: in memory).

    The digest is :func:`~youbot_opt.robot.source.urdf_digest`, as result files record it.

    This is what a sweep's manifest records of the robot: it does not depend
    on where the URDF, the installed package or the output folder lie, so a
    store resumes after a move or on another machine, and only with a file of
    the same content (an edited URDF is another robot).

    Raises
    ------
    ParameterError
        If the URDF file can no longer be read.
    """
    path = robot.urdf_path
    if path is None:
        return None
    return urdf_digest(path, robot.name)


def _refuse_0_1_0(out: Path) -> None:
    """Refuse a schema-3 store of 0.1.0 in ``out``: its problem holds a beta or a URDF path."""
    manifest = out / "manifest.json"
    try:
        stored = json.loads(manifest.read_text(encoding="utf-8"))
        problem = stored["params"]["problem"]
        old = stored["schema_version"] == SCHEMA_VERSION and (
            "beta" in problem or "urdf_path" in problem
        )
    except (OSError, ValueError, KeyError, TypeError):
        return  # none, or another form: the store checks it
    if old:
        raise ResultFileError(
            f"sweep manifest {manifest}: written by youbot_opt 0.1.0 (schema "
            f"{SCHEMA_VERSION}); run `python {MIGRATION_SCRIPT} {out}` to carry it forward"
        )


def sweep_params(solver: TrajOptSolver) -> dict[str, Any]:
    """JSON-ready description of the solver a sweep runs (part of its manifest).

    The problem's robot is named by :func:`robot_identity` (``"urdf_sha256"``),
    not by the URDF's path, so that the store does not depend on where files lie.
    """
    problem = solver.problem.describe()
    problem.pop("urdf_path", None)
    problem["urdf_sha256"] = robot_identity(solver.problem.robot)
    return {
        "problem": problem,
        "method": solver.method.name,
        "backend": solver.backend,
        "options": solver.options.to_dict(),
    }
