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

import math
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
    """Return the largest violation of ``lbg <= g <= ubg`` and ``lbx <= x <= ubx`` (>= 0).

    Not finite (NaN or inf) when an entry of ``x`` or ``g`` is not finite.
    """
    lbx, ubx, lbg, ubg = bounds
    of_g = float(np.max(np.maximum(lbg - g, g - ubg), initial=0.0))
    of_x = float(np.max(np.maximum(lbx - x, x - ubx), initial=0.0))
    return of_g + of_x if math.isnan(of_g + of_x) else max(of_g, of_x)


def better(a: Iterate, b: Iterate | None, feasibility_tol: float) -> bool:
    """Whether iterate ``a`` ranks above ``b`` (see the module docstring)."""
    return b is None or _ranks_above(a.violation, a.objective, b, feasibility_tol)


def _ranks_above(violation: float, objective: float, b: Iterate, feasibility_tol: float) -> bool:
    """Whether an iterate with this violation and objective ranks above ``b``."""
    a_ok, b_ok = violation <= feasibility_tol, b.violation <= feasibility_tol
    if a_ok and b_ok:
        return objective < b.objective
    if a_ok != b_ok:
        return a_ok
    return violation < b.violation


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
    arrays of their own (copies, safe to keep); IPOPT is never asked to stop.
    CasADi calls :meth:`eval_buffer` with its raw buffers (no ``DM`` is built);
    a subclass that needs less than every output overrides :meth:`take`,
    which receives read-only views valid only during the call.

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
        self._names = tuple(str(ca.nlpsol_out(i)) for i in range(ca.nlpsol_n_out()))
        self.construct(name, {})

    def record(self, values: dict[str, Array]) -> None:
        """Take one iterate's outputs (override this or :meth:`take`)."""
        raise NotImplementedError

    def take(self, views: dict[str, Array]) -> None:
        """Take an iterate's outputs as views into CasADi's buffers; copy them to :meth:`record`."""
        self.record({k: v.copy() for k, v in views.items()})

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

    def has_eval_buffer(self) -> bool:
        """Ask CasADi for :meth:`eval_buffer` (raw buffers) instead of :meth:`eval` (``DM``)."""
        return True

    def eval_buffer(self, arg: Sequence[memoryview], res: Sequence[memoryview]) -> int:
        """Pass the iterate to :meth:`take`; never stop IPOPT (the flag written is 0)."""
        views = {}
        for name, buffer in zip(self._names, arg, strict=True):
            if buffer is None:  # an output IPOPT does not provide (lam_p)
                continue
            view = np.frombuffer(buffer, dtype=np.float64)
            view.flags.writeable = False
            views[name] = view
        self.take(views)
        np.frombuffer(res[0], dtype=np.float64)[0] = 0.0
        return 0

    def eval(self, arg: Sequence[ca.DM]) -> list[ca.DM]:
        """Pass the iterate to :meth:`take` when called with ``DM`` (direct calls)."""
        self.take(
            {k: np.array(v, dtype=float).ravel() for k, v in zip(self._names, arg, strict=True)}
        )
        return [ca.DM(0)]


class BestIterateRecorder(NlpsolIterationCallback):
    """IPOPT ``iteration_callback`` that keeps the best iterate of the current run.

    Call :meth:`reset` with the run's bounds before each solve; :attr:`best`
    then holds the best finite iterate seen (or None) and :attr:`count` the
    number of iterates. Parameters as for :class:`NlpsolIterationCallback`.

    It runs once per IPOPT iteration, between factorizations that have just
    evicted its data from the CPU caches, so it touches as little memory as
    it can: an iterate whose objective cannot beat a feasible best is ranked
    from ``f`` alone; otherwise ``x`` and ``g`` are read in place (no copy),
    their violation formed in scratch arrays of the run, and ``x``, ``lam_x``,
    ``lam_g`` copied only when the iterate ranks above the best so far -- into
    arrays the recorder owns for the run (a later, better iterate of the same
    run overwrites them; :meth:`reset` starts new ones, so the best of an
    earlier run is never changed).
    """

    def __init__(self, name: str, nx: int, ng: int, n_par: int) -> None:
        self._bounds: tuple[Array, Array, Array, Array] | None = None
        self._scratch: tuple[Array, Array] = (np.empty(0), np.empty(0))
        self._owned: tuple[Array, Array, Array] | None = None
        self._tol = 0.0
        self.best: Iterate | None = None
        self.count = 0
        super().__init__(name, nx, ng, n_par)
        self._slots = tuple(self._names.index(name) for name in _RANKED)

    def reset(self, bounds: tuple[Array, Array, Array, Array], feasibility_tol: float) -> None:
        """Forget the previous run; rank the next one's iterates against these bounds."""
        lbx, ubx, lbg, ubg = (np.array(b, dtype=float).ravel() for b in bounds)
        self._bounds = (lbx, ubx, lbg, ubg)
        self._scratch = (np.empty(lbx.size), np.empty(lbg.size))
        self._owned = None  # the next best gets new arrays: earlier results stay intact
        self._tol = float(feasibility_tol)
        self.best = None
        self.count = 0

    def record(self, values: dict[str, Array]) -> None:
        """Rank this iterate and keep it if it is the best so far."""
        self.take(values)

    def take(self, views: dict[str, Array]) -> None:
        """Rank this iterate (views into CasADi's buffers); copy it if it is the best so far."""
        self._consider(*(views.get(name) for name in _RANKED))

    def eval_buffer(self, arg: Sequence[memoryview], res: Sequence[memoryview]) -> int:
        """Rank the iterate straight from CasADi's buffers (no dictionary, no copy)."""
        self._consider(*(None if arg[i] is None else np.frombuffer(arg[i]) for i in self._slots))
        np.frombuffer(res[0], dtype=np.float64)[0] = 0.0
        return 0

    def _consider(
        self,
        x: Array | None,
        f: Array | None,
        g: Array | None,
        lam_x: Array | None,
        lam_g: Array | None,
    ) -> None:
        iteration = self.count
        self.count += 1
        if self._bounds is None or x is None or f is None or g is None:
            return
        objective = float(f[0])
        if not math.isfinite(objective):
            return
        best = self.best
        if best is not None and best.violation <= self._tol and not objective < best.objective:
            return  # only a lower objective ranks above a feasible best, whatever x and g are
        violation = self._violation(x, g)
        if not math.isfinite(violation):  # some entry of x or g is not finite
            return
        if best is not None and not _ranks_above(violation, objective, best, self._tol):
            return
        if self._owned is None:
            self._owned = (np.empty(x.size), np.empty(x.size), np.empty(g.size))
        own_x, own_lam_x, own_lam_g = self._owned
        own_x[:] = x
        own_lam_x[:] = np.nan if lam_x is None else lam_x
        own_lam_g[:] = np.nan if lam_g is None else lam_g
        self.best = Iterate(
            x=own_x,
            lam_x=own_lam_x,
            lam_g=own_lam_g,
            objective=objective,
            violation=violation,
            iteration=iteration,
        )

    def _violation(self, x: Array, g: Array) -> float:
        """:func:`violation_of` in the run's scratch arrays (NaN if an entry is not finite)."""
        assert self._bounds is not None
        lbx, ubx, lbg, ubg = self._bounds
        sx, sg = self._scratch
        with np.errstate(invalid="ignore"):  # inf - inf in a non-finite iterate
            parts = (
                np.subtract(lbx, x, out=sx).max(initial=0.0),
                np.subtract(x, ubx, out=sx).max(initial=0.0),
                np.subtract(lbg, g, out=sg).max(initial=0.0),
                np.subtract(g, ubg, out=sg).max(initial=0.0),
            )
        total = float(sum(parts))
        return total if math.isnan(total) else float(max(parts))


_RANKED = ("x", "f", "g", "lam_x", "lam_g")  # the nlpsol outputs the recorder reads
