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

from collections.abc import Sequence
from typing import NamedTuple

import casadi as ca
import numpy as np

from youbot_opt._typing import Array

__all__ = ["Iterate", "BestIterateRecorder", "violation_of", "better"]


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


class BestIterateRecorder(ca.Callback):  # type: ignore[misc]
    """IPOPT ``iteration_callback`` that keeps the best iterate of the current run.

    Call :meth:`reset` with the run's bounds before each solve; :attr:`best`
    then holds the best finite iterate seen (or None) and :attr:`count` the
    number of iterates.

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
        self._bounds: tuple[Array, Array, Array, Array] | None = None
        self._tol = 0.0
        self.best: Iterate | None = None
        self.count = 0
        self.construct(name, {})

    def reset(self, bounds: tuple[Array, Array, Array, Array], feasibility_tol: float) -> None:
        """Forget the previous run; rank the next one's iterates against these bounds."""
        self._bounds = tuple(np.asarray(b, dtype=float).ravel() for b in bounds)  # type: ignore[assignment]
        self._tol = float(feasibility_tol)
        self.best = None
        self.count = 0

    # -- casadi.Callback interface
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
        """Rank this iterate and keep it if it is the best so far; never stop IPOPT."""
        names = [str(ca.nlpsol_out(i)) for i in range(len(arg))]
        values = dict(zip(names, arg, strict=True))
        iteration = self.count
        self.count += 1
        x = np.array(values["x"], dtype=float).ravel()
        g = np.array(values["g"], dtype=float).ravel()
        objective = float(values["f"])
        if self._bounds is None or not (np.all(np.isfinite(x)) and np.all(np.isfinite(g))):
            return [ca.DM(0)]
        candidate = Iterate(
            x=x,
            lam_x=np.array(values["lam_x"], dtype=float).ravel(),
            lam_g=np.array(values["lam_g"], dtype=float).ravel(),
            objective=objective,
            violation=violation_of(x, g, self._bounds),
            iteration=iteration,
        )
        if np.isfinite(objective) and better(candidate, self.best, self._tol):
            self.best = candidate
        return [ca.DM(0)]
