"""The on-disk store of a trajectory sweep: its identity and its payloads (spec ``trajopt.md``).

Owns :func:`open_store` (a :class:`~youbot_opt.sweeps.store.SweepStore` whose
payloads are :mod:`youbot_opt.trajopt.io` result files) and what its manifest
records: :func:`sweep_params` (problem, method, backend, options) with the robot
named by :func:`robot_identity`, the SHA-256 of its URDF's content, so a store
resumes wherever the output folder, the URDF or the package now lie. Stores
written when the robot was named by its absolute URDF path still resume.

    store = open_store("runs/ms", "multistart", {**sweep_params(solver), "seed": 0}, solver)
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path
from typing import Any

from youbot_opt.exceptions import ParameterError, YoubotOptWarning
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.source import urdf_digest
from youbot_opt.sweeps.store import SweepStore
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver

__all__ = ["open_store", "robot_identity", "sweep_params"]


def open_store(
    out: str | os.PathLike[str],
    kind: str,
    params: dict[str, Any],
    solver: TrajOptSolver,
    *,
    clean: bool = True,
) -> SweepStore:
    """Open a sweep store whose payloads are trajectory results.

    A store written before the robot was identified by content (its manifest
    holds the URDF's absolute ``"urdf_path"``) still resumes when that is the
    same robot: the same path, or a file there with the same content as the
    solver's URDF; it keeps its manifest (and so its items' binding).

    Parameters
    ----------
    out : path-like
        Output directory (created if missing).
    kind : str
        Kind of sweep (``"multistart"``, ``"pareto"``, ``"bounds"``).
    params : dict
        The sweep's defining parameters, from :func:`sweep_params` and the
        sweep's own (a rerun with others is refused).
    solver : TrajOptSolver
        Its robot loads the stored results (:mod:`youbot_opt.trajopt.io` files).
    clean : bool
        Remove leftover temporary files (not in a shard run: other shards
        may be writing into the same folder).

    Returns
    -------
    SweepStore
        The store.
    """
    from youbot_opt.trajopt.io import load_result, save_result

    robot = solver.problem.robot

    def load(path: Path) -> TrajOptResult:
        return load_result(path, robot=robot)

    params = _as_stored(Path(out), _with_stored_beta(Path(out), params), robot)
    return SweepStore(
        out, kind=kind, params=params, save=save_result, load=load, suffix=".npz", clean=clean
    )


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


def _with_stored_beta(out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """``params`` with the problem ``"beta"`` of a 0.1.0 store in ``out``, if it has one.

    0.1.0 problems carried a default time weight; no sweep solved with it (each
    records the weight it solved at: ``"beta"``, ``"betas"``), so it does not
    tell two sweeps apart.
    """
    try:
        stored = json.loads((out / "manifest.json").read_text(encoding="utf-8"))["params"]
        beta = stored["problem"]["beta"]
    except (OSError, ValueError, KeyError, TypeError):
        return params
    return {**params, "problem": {**params["problem"], "beta": beta}}


def _as_stored(out: Path, params: dict[str, Any], robot: RobotModel) -> dict[str, Any]:
    """``params`` as an older store in ``out`` wrote them, if its URDF path names this robot.

    The same path, or a file there with this robot's content, is this robot;
    a path whose file is gone is taken by its file name, with a warning (the
    rest of the manifest, robot name and sizes included, must still match).
    """
    try:  # the store checks the manifest itself; this only recognises the older form
        stored = json.loads((out / "manifest.json").read_text(encoding="utf-8"))["params"]
        old_problem, problem = stored["problem"], params["problem"]
        path = old_problem["urdf_path"]
    except (OSError, ValueError, KeyError, TypeError):
        return params
    if "urdf_sha256" in old_problem or not isinstance(path, str | None):
        return params
    here = robot.urdf_path
    if path is None or here is None:
        same = path is None and here is None
    elif Path(path) == Path(here):
        same = True
    elif Path(path).exists():  # moved, the old file still there: the same content?
        try:
            same = urdf_digest(path, robot.name) == problem.get("urdf_sha256")
        except ParameterError:
            same = False
    else:
        same = Path(path).name == Path(here).name
        if same:
            warnings.warn(
                f"the sweep in {out} was written before robots were identified by content: "
                f"its URDF {path} is gone, so robot {robot.name!r} is taken to be the same "
                f"by file name ({Path(here).name}); the results are resumed",
                YoubotOptWarning,
                stacklevel=4,
            )
    if not same:
        return params  # the store reports the difference
    legacy = {k: v for k, v in problem.items() if k != "urdf_sha256"}
    return {**params, "problem": {**legacy, "urdf_path": path}}


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
