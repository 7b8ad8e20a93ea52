"""Duration and work against payload mass: :func:`payload_sweep` (issue 30, item 1).

For each mass the robot of the problem carries the payload
(:meth:`RobotModel.with_payload <youbot_opt.robot.model.RobotModel.with_payload>`:
the dynamics change, so one solver is built per mass) and
:func:`~youbot_opt.trajopt.multistart.run_multistart` solves it from seeded
starts; :class:`PayloadSweep` holds the best start's T and W per mass.

>>> sweep = payload_sweep(study1_problem(30), [0.0, 0.25, 0.5], n_starts=8)  # doctest: +SKIP
>>> sweep.table()  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.payload import Payload
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.multistart import MultistartResult, run_multistart
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver

__all__ = ["PayloadPoint", "PayloadSweep", "payload_sweep"]


@dataclass(frozen=True, slots=True, kw_only=True)
class PayloadPoint:
    """The best solve of one payload mass.

    Attributes
    ----------
    mass : float
        Payload mass in [kg].
    duration : float
        ``T`` of the best converged start in [s]; NaN if none converged.
    work : float
        ``W`` of the best converged start in [N^2 m^2 s]; NaN if none converged.
    objective : float
        ``beta T + (1 - beta) W`` of the best start; NaN if none converged.
    n_converged, n_starts : int
        Converged starts, and starts.
    result : TrajOptResult or None
        The best start's result (its robot carries the payload); None if none converged.
    """

    mass: float
    duration: float
    work: float
    objective: float
    n_converged: int
    n_starts: int
    result: TrajOptResult | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class PayloadSweep:
    """Best T and W per payload mass.

    Attributes
    ----------
    points : tuple of PayloadPoint
        One per mass, in the order given.
    payload : Payload
        The payload whose mass was varied (centre of mass, inertia, frame).
    beta, bound_scale : float
        Time weight and bound scale of every solve.
    """

    points: tuple[PayloadPoint, ...]
    payload: Payload
    beta: float
    bound_scale: float

    @property
    def masses(self) -> Array:
        """Payload masses in [kg], shape (n,)."""
        return np.array([p.mass for p in self.points])

    @property
    def durations(self) -> Array:
        """Best durations ``T`` in [s], shape (n,) (NaN where none converged)."""
        return np.array([p.duration for p in self.points])

    @property
    def works(self) -> Array:
        """Best works ``W`` in [N^2 m^2 s], shape (n,) (NaN where none converged)."""
        return np.array([p.work for p in self.points])

    def table(self) -> str:
        """Return a plain-text table: mass [kg], T [s], W, objective, converged starts."""
        lines = [
            f"{'mass [kg]':>10} {'T [s]':>9} {'W [N^2 m^2 s]':>14} {'f':>10} {'converged':>10}"
        ]
        for p in self.points:
            lines.append(
                f"{p.mass:10.4g} {p.duration:9.4f} {p.work:14.4f} {p.objective:10.4f} "
                f"{p.n_converged:>5}/{p.n_starts:<4}"
            )
        return "\n".join(lines)


def payload_sweep(
    problem: TrajOptProblem,
    masses: Sequence[float],
    *,
    payload: Payload | None = None,
    method: str = "trapezoidal",
    n_starts: int = 8,
    beta: float = 0.5,
    bound_scale: float = 1.0,
    seed: int = 0,
    include_straight: bool = True,
    sweep: SweepOptions = SweepOptions(),  # noqa: B008 - frozen, so sharing it is safe
) -> PayloadSweep:
    """Solve ``problem`` with the robot carrying each payload mass; keep the best start's T, W.

    Parameters
    ----------
    problem : TrajOptProblem
        The problem; its robot must carry no payload.
    masses : sequence of float
        Payload masses in [kg], each >= 0.
    payload : Payload, optional
        Centre of mass, inertia and frame of the payload (its mass is replaced
        by each of ``masses``); a point mass at the tip by default.
    method : str
        Transcription name (``"trapezoidal"``, ``"hermite_simpson"``, ``"radau"``).
    n_starts : int
        Random spline starts per mass (:func:`run_multistart`).
    beta : float
        Time weight in [0, 1].
    bound_scale : float
        Bound scale factor (> 0, 1.0 = data sheet).
    seed : int
        Base seed of the starts (the same starts for every mass).
    include_straight : bool
        Also start from the straight line.
    sweep : SweepOptions
        How the starts of one mass run (``shard`` is not supported here).

    Returns
    -------
    PayloadSweep
        The best converged start per mass.

    Raises
    ------
    ParameterError
        If a mass is not finite and >= 0, ``masses`` is empty, the robot
        already carries a payload, or ``sweep.shard`` is set.
    """
    values = [float(m) for m in masses]
    if not values or not all(math.isfinite(m) and m >= 0.0 for m in values):
        raise ParameterError(
            f"masses must be a non-empty list of finite masses >= 0 [kg], got {list(masses)!r}",
            name="masses",
        )
    if sweep.shard is not None:
        raise ParameterError("payload_sweep runs whole multistarts: sweep.shard must be None")
    base = Payload(mass=0.0) if payload is None else payload
    points: list[PayloadPoint] = []
    for mass in values:
        robot = problem.robot.with_payload(dataclasses.replace(base, mass=mass))
        solver = TrajOptSolver(dataclasses.replace(problem, robot=robot), method=method)
        starts = run_multistart(
            solver,
            n_starts,
            beta=beta,
            bound_scale=bound_scale,
            seed=seed,
            include_straight=include_straight,
            sweep=sweep,
        )
        assert isinstance(starts, MultistartResult)  # no shard: a whole multistart
        best = starts.best
        nan = math.nan
        points.append(
            PayloadPoint(
                mass=mass,
                duration=nan if best is None else best.duration,
                work=nan if best is None else best.work,
                objective=nan if best is None else best.objective,
                n_converged=starts.n_converged,
                n_starts=starts.n_starts,
                result=None if best is None else best.result,
            )
        )
    return PayloadSweep(
        points=tuple(points), payload=base, beta=float(beta), bound_scale=float(bound_scale)
    )
