"""The on-disk store of a trajectory sweep: its identity and its payloads (spec ``trajopt.md``).

Owns :func:`result_codec` (the :class:`~youbot_opt.sweeps.store.Codec` of a
sweep whose payloads are :mod:`youbot_opt.trajopt.io` result files) and what its
manifest records: :func:`sweep_params` (problem, method, backend, options) with the robot
named by :func:`robot_identity`, the SHA-256 of its URDF's content, so a store
resumes wherever the output folder, the URDF or the package now lie; and
:func:`open_refined`, the store of a study's refined plans (:func:`refined_key`,
:func:`check_refined`; docs/refinement.md, "Stored refined plans").

    params = {**sweep_params(solver), "seed": 0}
    store = open_store("runs/ms", "multistart", params, result_codec(solver))
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from youbot_opt._files import MIGRATION_SCRIPT, array_digest, json_digest
from youbot_opt._typing import JSONDict
from youbot_opt.collision.clearance import clearance_checker, clearance_document
from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.source import urdf_digest
from youbot_opt.sweeps.store import SCHEMA_VERSION, Codec, SweepStore, open_store
from youbot_opt.trajopt.certify import Tolerances
from youbot_opt.trajopt.clearance import certify_plan_clearance
from youbot_opt.trajopt.mesh import collocation_error
from youbot_opt.trajopt.optimality import first_order
from youbot_opt.trajopt.refine import Refined, RefinementBudget
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep import StartJobChain, StartJobs

__all__ = [
    "ItemMaking",
    "budget_digest",
    "check_item",
    "check_refined",
    "jobs_making",
    "open_refined",
    "plan_digest",
    "refined_codec",
    "refined_key",
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


def jobs_making(jobs: StartJobs | StartJobChain) -> ItemMaking:
    """Return what makes each item of start jobs (``jobs.job(key)``): beta, bound scale, seed."""
    return functools.partial(_job_making, jobs)


def _job_making(jobs: StartJobs | StartJobChain, key: str) -> dict[str, float | int | None]:
    job = jobs.job(key)
    return {"beta": job.beta, "bound_scale": job.bound_scale, "seed": job.seed}


def _problem(result_or_solver: TrajOptResult | TrajOptSolver) -> JSONDict:
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


def sweep_params(solver: TrajOptSolver) -> JSONDict:
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


# ------------------------------------------------------ a study's refined plans
_ITEM_CHARS = 60  # of the sweep key in a refined key (a store key holds at most 100)


def plan_digest(result: TrajOptResult) -> str:
    """SHA-256 (hex) of a plan: transcription, beta, bound scale, grid and every variable.

    A plan saved and loaded again (:mod:`youbot_opt.trajopt.io`) has the same digest.
    """
    return json_digest(
        {
            "method": result.method,
            "beta": float(result.beta),
            "bound_scale": float(result.bound_scale),
            "seed": result.seed,
            "n_knots": result.problem.n_knots,
            "grid": None if result.grid is None else array_digest(np.asarray(result.grid, float)),
            "variables": {
                name: [array_digest(np.asarray(v, dtype=float)), list(np.shape(v))]
                for name, v in sorted(result.variables.items())
            },
        }
    )


def budget_digest(budget: RefinementBudget) -> str:
    """SHA-256 (hex) of every field of a :class:`RefinementBudget` (its tolerances too)."""
    body = {f.name: getattr(budget, f.name) for f in dataclasses.fields(budget)}
    tol = budget.tolerances
    body["tolerances"] = None if tol is None else dataclasses.asdict(tol)
    return json_digest(body)


def refined_key(item: str, grid: TrajOptResult, budget: RefinementBudget) -> str:
    """Return the store key of ``grid`` (item ``item`` of a sweep) refined with ``budget``.

    ``<item>.<16 hex of plan_digest(grid)>.<12 hex of budget_digest(budget)>``; the
    item's key is cut to 60 characters (the digest of its plan tells items apart).
    """
    return f"{item[:_ITEM_CHARS]}.{plan_digest(grid)[:16]}.{budget_digest(budget)[:12]}"


def _refined_problem(result: TrajOptResult, folder: Path) -> dict[str, object]:
    """Return the problem's description but its grid size, with its clearance."""
    desc = result.problem.describe()
    for name in ("urdf_path", "n_knots"):
        desc.pop(name, None)
    spec = result.problem.clearance
    desc["clearance"] = None if spec is None else clearance_document(spec, folder)
    return desc


def check_refined(
    grids: Mapping[str, TrajOptResult],
    budget: RefinementBudget,
    folder: Path,
    key: str,
    refined: Refined,
) -> str | None:
    """Why ``refined``, read back as ``key``, is not the refinement of that grid plan (None: it is).

    ``refined`` comes from :func:`~youbot_opt.trajopt.io.load_refined` (the
    independent check and the certificate already re-run); refused when the
    loaded plan fails its check, when its saved certificate claim fails at the
    caller's tolerances, when its budget is not ``budget``, when it is stored
    as certified but its collocation error exceeds ``budget.tolerance`` or
    (with a clearance) its clearance between the knots fails, or when it is not a
    refinement of ``grids[key]``: robot, transcription, problem (boundary
    states, bounds, clearance: all but the grid's size), beta, bound scale,
    seed, round 0 on the grid plan's knots and objective, and its objective
    re-evaluated at its beta (relative :data:`OBJECTIVE_RTOL`).
    """
    grid = grids.get(key)
    if grid is None:
        return f"{key!r} is no refined plan of this study"
    result, record = refined
    if not result.success:
        return f"the stored plan fails its check on load ({result.status.value})"
    if record.certificate is not None and not record.certified:
        return f"its certificate fails on load ({record.reason})"
    if record.budget != budget:
        return f"refined with another budget ({record.budget.describe()})"
    if record.certified:  # the rest of the verdict: the collocation error, the clearance
        why = _certified_on_load(result, budget)
        if why:
            return why
    if result.problem.robot is not grid.problem.robot:
        return "another robot"
    if result.method != grid.method:
        return f"transcription {result.method!r}, the grid plan's is {grid.method!r}"
    mine, theirs = _refined_problem(grid, folder), _refined_problem(result, folder)
    if mine != theirs:
        fields = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
        return f"its problem differs in {', '.join(fields)}"
    for name in ("beta", "bound_scale", "seed"):
        if getattr(result, name) != getattr(grid, name):
            return f"{name} = {getattr(result, name)!r}, the grid plan's is {getattr(grid, name)!r}"
    first = record.rounds[0] if record.rounds else None
    if first is None or (first.n_knots, first.objective) != (grid.problem.n_knots, grid.objective):
        return "its first round is not the grid plan"
    value = result.beta * result.duration + (1.0 - result.beta) * result.work
    if not (
        math.isfinite(value)
        and abs(result.objective - value) <= OBJECTIVE_RTOL * max(1.0, abs(value))
    ):
        return f"objective {result.objective:.9g}, but its trajectory gives {value:.9g}"
    return None


def _certified_on_load(result: TrajOptResult, budget: RefinementBudget) -> str:
    """Why a plan stored as certified is not, besides its certificate ("": it is).

    As :func:`~youbot_opt.trajopt.refine.refine` decides it: every interval's
    collocation error within ``budget.tolerance`` and, with a clearance, the
    exact clearance between the knots (the loader checks it at the knots).
    """
    error = collocation_error(result)
    if not error.max <= budget.tolerance:
        return f"stored as certified, but its max error is {error.max:.3g} > {budget.tolerance:g}"
    spec = result.problem.clearance
    if spec is not None and result.trajectory is not None:
        robot = result.problem.robot
        checker = clearance_checker(robot, spec)
        clear = certify_plan_clearance(result.trajectory, robot, checker, margin=spec.margin)
        if not clear.certified:
            return "stored as certified, but its clearance between the knots fails"
    return ""


def _save(refined: Refined, path: Path) -> Path:
    """Write a refined plan; a write the system refuses raises its ``OSError`` (as the store's)."""
    from youbot_opt.trajopt.io import save_result

    try:
        return save_result(refined.result, path, refinement=refined.refinement)
    except ResultFileError as exc:
        if isinstance(exc.__cause__, OSError):  # full disk, read-only folder: the path, the fix
            raise exc.__cause__ from None
        raise


def refined_codec(
    solver: TrajOptSolver,
    grids: Mapping[str, TrajOptResult],
    budget: RefinementBudget,
    folder: Path,
) -> Codec[Refined]:
    """Return how refined plans are stored: result files with their refinement record.

    Read back by :func:`~youbot_opt.trajopt.io.load_refined` on the solver's
    robot, certified again at ``budget.tolerances`` (the certificate's defaults
    when None), then :func:`check_refined` against ``grids`` (by store key).
    """
    from youbot_opt.trajopt.io import load_refined

    tolerances = budget.tolerances or Tolerances()
    return Codec(
        save=_save,
        load=functools.partial(load_refined, robot=solver.problem.robot, tolerances=tolerances),
        suffix=".npz",
        check=functools.partial(check_refined, dict(grids), budget, folder),
    )


def open_refined(
    out: str | os.PathLike[str],
    solver: TrajOptSolver,
    grids: Mapping[str, TrajOptResult],
    budget: RefinementBudget,
) -> SweepStore[Refined]:
    """Open (or create) the store of a study's refined plans in ``out``.

    Parameters
    ----------
    out : path-like
        Its folder (``refined/`` of the run folder).
    solver : TrajOptSolver
        The study's solver (the grid plans' problem; its :func:`sweep_params`
        are the store's parameters).
    grids : mapping of str to TrajOptResult
        The grid plans to refine, by :func:`refined_key`.
    budget : RefinementBudget
        The refinement budget (part of every key).

    Raises
    ------
    ParameterError
        If ``out`` holds the refined plans of another problem.
    """
    folder = Path(out)
    codec = refined_codec(solver, grids, budget, folder)
    return open_store(folder, "refined", sweep_params(solver), codec)
