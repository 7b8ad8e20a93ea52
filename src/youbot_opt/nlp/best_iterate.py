"""The best iterate of an IPOPT run, kept by an iteration callback.

When IPOPT fails (iteration cap, restoration failure, an infeasible problem),
its last iterate is often not its best: it may have wandered away from a
nearly feasible point while trying to restore feasibility. A failed solve in
youbot_opt returns the best iterate instead, so the user gets the most useful
point the solver saw, with the failure status.

"Best" is lexicographic, the usual filter-method ranking: among iterates whose
largest constraint or bound violation is within the feasibility tolerance, the
lowest objective; if none is, the smallest violation. A converged solve keeps
IPOPT's own final iterate (it is the KKT point, with its multipliers).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import NamedTuple

import casadi as ca
import numpy as np

from youbot_opt._typing import Array

__all__ = [
    "Iterate",
    "NlpsolIterationCallback",
    "BestIterateRecorder",
    "violation_of",
    "better",
    "best_of",
]


class Iterate(NamedTuple):
    """One IPOPT iterate with what ranks it.

    Attributes
    ----------
    x, lam_x, lam_g : numpy.ndarray
        Primal variables and the multiplier estimates of that iteration.
    objective : float
        NLP objective at ``x`` (its unit: that of the objective).
    violation : float
        Largest violation of a constraint row or variable bound, in the row's unit.
    iteration : int
        Iteration number (0 = the starting point).
    """

    x: Array
    lam_x: Array
    lam_g: Array
    objective: float
    violation: float
    iteration: int


def violation_of(x: Array, g: Array, bounds: tuple[Array, Array, Array, Array]) -> float:
    """Return the largest violation of ``lbg <= g <= ubg`` and ``lbx <= x <= ubx`` (>= 0)."""
    lbx, ubx, lbg, ubg = bounds
    return max(
        float(np.max(np.maximum(lbg - g, g - ubg), initial=0.0)),
        float(np.max(np.maximum(lbx - x, x - ubx), initial=0.0)),
    )


def better(a: Iterate, b: Iterate | None, feasibility_tol: float) -> bool:
    """Whether iterate ``a`` ranks above ``b`` (see the module docstring)."""
    if b is None:
        return True
    a_ok, b_ok = a.violation <= feasibility_tol, b.violation <= feasibility_tol
    if a_ok and b_ok:
        return a.objective < b.objective
    if a_ok != b_ok:
        return a_ok
    return a.violation < b.violation


def best_of(final: Iterate, visited: Iterable[Iterate], feasibility_tol: float) -> Iterate:
    """Return the best of ``final`` and the ``visited`` iterates (see the module docstring).

    Parameters
    ----------
    final : Iterate
        The iterate the solver ended with; it is kept unless another ranks strictly above.
    visited : iterable of Iterate
        Earlier iterates, in order; those with a non-finite objective or
        violation are skipped.
    feasibility_tol : float
        Largest violation of a feasible iterate (unit of the rows).

    Returns
    -------
    Iterate
        ``final`` itself, or the first iterate that ranks best.
    """
    best = final
    for candidate in visited:
        if not (np.isfinite(candidate.objective) and np.isfinite(candidate.violation)):
            continue
        if better(candidate, best, feasibility_tol):
            best = candidate
    return best


class NlpsolIterationCallback(ca.Callback):  # type: ignore[misc]
    """Base of IPOPT ``iteration_callback`` objects: takes every ``nlpsol`` output.

    Subclasses implement :meth:`record`, which receives the iterate's outputs
    by name (``x``, ``f``, ``g``, ``lam_x``, ``lam_g``, ``lam_p``) as flat
    arrays and floats; IPOPT is never asked to stop.

    Parameters
    ----------
    name : str
        Name of the CasADi callback.
    nx, ng, n_par : int
        Sizes of the NLP's ``x``, ``g`` and ``p``.
    """

    def __init__(self, name: str, nx: int, ng: int, n_par: int) -> None:
        ca.Callback.__init__(self)
        self._sizes = {"f": 1, "x": nx, "g": ng, "lam_x": nx, "lam_g": ng, "lam_p": n_par}
        self.construct(name, {})

    def record(self, values: dict[str, Array]) -> None:
        """Take one iterate's outputs (override)."""
        raise NotImplementedError

    def get_n_in(self) -> int:
        """Return the number of inputs: every output of ``nlpsol``."""
        return int(ca.nlpsol_n_out())

    def get_n_out(self) -> int:
        """Return the number of outputs (one flag, 0 = go on)."""
        return 1

    def get_name_in(self, i: int) -> str:
        """Return the name of input ``i`` (``nlpsol``'s output names)."""
        return str(ca.nlpsol_out(i))

    def get_name_out(self, i: int) -> str:
        """Return the name of the output."""
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        """Return the dense column shape of input ``i``."""
        return ca.Sparsity.dense(self._sizes.get(str(ca.nlpsol_out(i)), 0), 1)

    def eval(self, arg: Sequence[ca.DM]) -> list[ca.DM]:
        """Pass the iterate to :meth:`record`; never stop IPOPT."""
        names = [str(ca.nlpsol_out(i)) for i in range(len(arg))]
        self.record({k: np.array(v, dtype=float).ravel() for k, v in zip(names, arg, strict=True)})
        return [ca.DM(0)]


class BestIterateRecorder(NlpsolIterationCallback):
    """IPOPT ``iteration_callback`` that keeps the best iterate of the current run.

    Call :meth:`reset` with the run's bounds before each solve; :attr:`best`
    then holds the best finite iterate seen (or None) and :attr:`count` the
    number of iterates. Parameters as for :class:`NlpsolIterationCallback`.
    """

    def __init__(self, name: str, nx: int, ng: int, n_par: int) -> None:
        self._bounds: tuple[Array, Array, Array, Array] | None = None
        self._tol = 0.0
        self.best: Iterate | None = None
        self.count = 0
        super().__init__(name, nx, ng, n_par)

    def reset(self, bounds: tuple[Array, Array, Array, Array], feasibility_tol: float) -> None:
        """Forget the previous run; rank the next one's iterates against these bounds."""
        self._bounds = tuple(np.asarray(b, dtype=float).ravel() for b in bounds)  # type: ignore[assignment]
        self._tol = float(feasibility_tol)
        self.best = None
        self.count = 0

    def record(self, values: dict[str, Array]) -> None:
        """Rank this iterate and keep it if it is the best so far."""
        iteration = self.count
        self.count += 1
        x, g, objective = values["x"], values["g"], float(values["f"][0])
        if self._bounds is None or not (np.all(np.isfinite(x)) and np.all(np.isfinite(g))):
            return
        candidate = Iterate(
            x=x,
            lam_x=values["lam_x"],
            lam_g=values["lam_g"],
            objective=objective,
            violation=violation_of(x, g, self._bounds),
            iteration=iteration,
        )
        if np.isfinite(objective) and better(candidate, self.best, self._tol):
            self.best = candidate
