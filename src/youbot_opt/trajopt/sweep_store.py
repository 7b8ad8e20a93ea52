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
from pathlib import Path
from typing import Any

from youbot_opt._files import MIGRATION_SCRIPT
from youbot_opt.exceptions import ResultFileError
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.source import urdf_digest
from youbot_opt.sweeps.store import SCHEMA_VERSION, Codec
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver

__all__ = ["result_codec", "robot_identity", "sweep_params"]


def result_codec(solver: TrajOptSolver) -> Codec[TrajOptResult]:
    """Return how a trajectory sweep's payloads are stored: :mod:`youbot_opt.trajopt.io` files.

    Its robot loads the stored results. A store written by 0.1.0 (its problem
    holds a ``"beta"`` or the URDF's absolute ``"urdf_path"``) is refused:
    ``scripts/migrate_0_1_0.py`` carries it forward.
    """
    from youbot_opt.trajopt.io import load_result, save_result

    return Codec(
        save=save_result,
        load=functools.partial(load_result, robot=solver.problem.robot),
        suffix=".npz",
        refuse_old=_refuse_0_1_0,
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
