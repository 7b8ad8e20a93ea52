"""What the adaptive steppers share: their state, the first step and the step cut on a knot.

Owns :class:`Stepper`, the base of :class:`~youbot_opt.dynamics.dop853.Dop853` and
:class:`~youbot_opt.dynamics.radau5.Radau5`: a stack of rows integrated one accepted
step at a time towards a ``t_bound`` it never passes, so a caller can stop on a knot,
an event or a deadline. Also :func:`initial_step` (Hairer's first step size), the
step-size controller's bounds and the trial step, each as SciPy's ``solve_ivp``.

>>> stepper = Dop853(fun, 0.0, y0, rtol=1e-10, atol=1e-12, t_bound=1.0)  # doctest: +SKIP
>>> while stepper.t < 1.0 and stepper.step(1.0): pass  # doctest: +SKIP
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import ClassVar, NamedTuple

import numpy as np

from youbot_opt._typing import Array

__all__ = [
    "MAX_FACTOR",
    "MIN_FACTOR",
    "SAFETY",
    "TOO_SMALL_STEP",
    "Rhs",
    "Stepper",
    "TrialStep",
    "initial_step",
    "min_step",
    "next_step_size",
    "trial_step",
]

Rhs = Callable[[float, Array], Array]
"""``f(t, y) -> dy/dt`` on a stack of rows, shape (rows, n) in and out."""

TOO_SMALL_STEP = "Required step size is less than spacing between numbers."
"""Why a step fails: SciPy's message for the same condition."""

SAFETY = 0.9
"""Safety factor of the step-size control (dimensionless), as ``dop853.f`` and SciPy."""
MIN_FACTOR = 0.2
"""Largest decrease of a step in one control decision (dimensionless), as SciPy."""
MAX_FACTOR = 10.0
"""Largest increase of a step in one control decision (dimensionless), as SciPy."""


def _rms_rows(x: Array) -> Array:
    """RMS norm of each row of ``x`` (shape (rows, n))."""
    return np.sqrt(np.einsum("ij,ij->i", x, x) / x.shape[1])


def initial_step(
    fun: Rhs,
    t0: float,
    y0: Array,
    f0: Array,
    t_bound: float,
    rtol: float,
    atol: float,
    *,
    order: int = 7,
) -> float:
    """Choose a first step size, as Hairer's ``dop853.f`` and SciPy's ``select_initial_step``.

    Each row's suggestion is computed from the sizes of ``y0``, ``f0`` and a
    difference estimate of the second derivative (one more evaluation of
    ``fun``); the smallest row's is returned (one row: SciPy's value).

    Parameters
    ----------
    fun : callable
        Right-hand side ``f(t, y)`` on a stack of rows.
    t0 : float
        Initial time.
    y0, f0 : ndarray, shape (rows, n)
        Initial state and its derivative ``fun(t0, y0)``.
    t_bound : float
        End of the integration (the step does not exceed ``t_bound - t0``).
    rtol, atol : float
        Relative and absolute tolerances.
    order : int, optional
        Order of the method's error estimate (7 for DOP853, 3 for Radau IIA):
        the local error is taken as proportional to ``h**(order + 1)``.

    Returns
    -------
    float
        The suggested first step (> 0) in the unit of ``t``, or NaN if the
        derivative is not finite.
    """
    length = abs(t_bound - t0)
    if length == 0.0:
        return 0.0
    with np.errstate(all="ignore"):  # a state or derivative that is not finite gives NaN
        scale = atol + np.abs(y0) * rtol
        d0, d1 = _rms_rows(y0 / scale), _rms_rows(f0 / scale)
        h0_rows = np.where((d0 < 1e-5) | (d1 < 1e-5), 1e-6, 0.01 * d0 / d1)
    if not np.all(np.isfinite(h0_rows)):
        return float("nan")  # the first step fails
    h0 = min(float(np.min(h0_rows)), length)
    direction = 1.0 if t_bound > t0 else -1.0
    f1 = fun(t0 + h0 * direction, y0 + h0 * direction * f0)
    with np.errstate(all="ignore"):
        d2 = _rms_rows((f1 - f0) / scale) / h0
        h1_rows = np.where(
            (d1 <= 1e-15) & (d2 <= 1e-15),
            max(1e-6, h0 * 1e-3),
            (0.01 / np.maximum(d1, d2)) ** (1.0 / (order + 1)),
        )
    if np.isnan(h1_rows).any():
        return float("nan")
    return float(min(100.0 * h0, float(np.min(h1_rows)), length))


def min_step(t: float) -> float:
    """Return the smallest step size allowed at ``t``, as SciPy's steppers.

    Parameters
    ----------
    t : float
        The current time.

    Returns
    -------
    float
        Ten times the spacing of floating-point numbers at ``t``, in the unit of ``t``.
    """
    return float(10.0 * abs(np.nextafter(t, np.inf) - t))


class TrialStep(NamedTuple):
    """One step to try (:func:`trial_step`).

    Attributes
    ----------
    t_new : float
        Where the step ends.
    h : float
        Its size ``t_new - t``, in the unit of ``t``.
    cut : bool
        Whether it was cut to end on ``t_bound``.
    """

    t_new: float
    h: float
    cut: bool


def trial_step(t: float, h_abs: float, t_bound: float) -> TrialStep:
    """Return the step of size ``h_abs`` from ``t``, cut to end on ``t_bound`` if it would pass it.

    Parameters
    ----------
    t : float
        The current time.
    h_abs : float
        The controller's step size (> 0), in the unit of ``t``.
    t_bound : float
        The time not to pass (> ``t``).

    Returns
    -------
    TrialStep
        The step's end, size and whether it was cut.
    """
    t_new = t + h_abs
    cut = t_new >= t_bound
    if cut:
        t_new = t_bound
    return TrialStep(t_new, t_new - t, cut)


def next_step_size(
    h_abs: float, factor: float, *, wanted: float, cut: bool, rejected: bool
) -> float:
    """Return the size of the next step to try after an accepted step.

    The controller's ``h_abs * factor``; but a step cut to end on ``t_bound``
    was short because of the cut, not the error: when it was accepted at its
    first trial and the controller would not shrink the step (``factor >= 1``),
    the next step may again be as long as the one wanted before the cut.

    Parameters
    ----------
    h_abs : float
        Size of the accepted step, in the unit of ``t``.
    factor : float
        The controller's factor (dimensionless).
    wanted : float
        The step size tried first, before any cut.
    cut : bool
        Whether the step was cut to end on ``t_bound``.
    rejected : bool
        Whether a trial of this step was rejected.

    Returns
    -------
    float
        ``max(h_abs * factor, wanted)`` after a cut step accepted at its first
        trial with ``factor >= 1``, else ``h_abs * factor``.
    """
    h_next = h_abs * factor
    if cut and not rejected and factor >= 1.0:
        return max(h_next, wanted)
    return h_next


class Stepper(ABC):
    """An adaptive integrator of a stack of rows, one accepted step at a time.

    The stepper holds the current time ``t``, state ``y`` and derivative ``f``
    (``fun(t, y)``) and the next step size. A method's :meth:`step` takes one
    accepted step towards ``t_bound`` without passing it; its :meth:`dense`
    evaluates the last step's continuous extension. Errors are measured per row
    and the largest row's decides: with one row a method is SciPy's.

    Parameters
    ----------
    fun : callable
        Right-hand side ``f(t, y)``, shape (rows, n) in and out. A step never
        evaluates it beyond ``t_bound``, so ``fun`` may change where a caller
        stops (a knot): then call :meth:`refresh`.
    t0 : float
        Initial time.
    y0 : ndarray, shape (rows, n)
        Initial state.
    rtol, atol : float
        Relative and absolute tolerances (``atol`` in the unit of ``y``).
    t_bound : float
        Where the first step is aimed (for :func:`initial_step`).
    first_step : float, optional
        The first step size; by default :func:`initial_step`'s for the method's
        :attr:`error_order`.
    f0 : ndarray, shape (rows, n), optional
        ``fun(t0, y0)`` if known.

    Attributes
    ----------
    error_order : int
        Order of the method's error estimate (a class constant).
    t : float
        Current time.
    y : ndarray, shape (rows, n)
        Current state.
    f : ndarray, shape (rows, n)
        ``fun(t, y)``.
    h_abs : float
        Size of the next step to try.
    t_old : float
        Start of the last accepted step (``t0`` before any).
    nfev : int
        Evaluations of ``fun`` so far.
    message : str
        Why the last :meth:`step` failed ("" if it did not).
    """

    error_order: ClassVar[int]

    def __init__(
        self,
        fun: Rhs,
        t0: float,
        y0: Array,
        *,
        rtol: float,
        atol: float,
        t_bound: float,
        first_step: float | None = None,
        f0: Array | None = None,
    ) -> None:
        self.fun = fun
        self.rtol, self.atol = float(rtol), float(atol)
        self.t = self.t_old = float(t0)
        self.y = self.y_old = np.array(y0, dtype=float)
        self.nfev = 1 if f0 is None else 0
        self.f = np.array(fun(self.t, self.y) if f0 is None else f0, dtype=float)
        if first_step is None:
            self.nfev += 1
            first_step = initial_step(
                fun, self.t, self.y, self.f, t_bound, self.rtol, self.atol, order=self.error_order
            )
        self.h_abs = float(first_step)
        self.message = ""
        self._h = 0.0  # the last accepted step, signed

    def refresh(self) -> None:
        """Re-evaluate ``f = fun(t, y)`` after ``fun`` changed at the current time.

        The last step's dense output stays the step's (if it evaluates ``fun``,
        see the method's :meth:`dense`).
        """
        self.nfev += 1
        self.f = np.array(self.fun(self.t, self.y), dtype=float)

    @abstractmethod
    def step(self, t_bound: float) -> bool:
        """Take one accepted step towards ``t_bound``, at most to ``t_bound``.

        The step size is the controller's, cut to end on ``t_bound`` if it would
        pass it (:func:`trial_step`); a rejected step is retried smaller. After a
        cut step, the next step may again be as long as the one before the cut
        (:func:`next_step_size`).

        Parameters
        ----------
        t_bound : float
            The time not to pass (> ``t``).

        Returns
        -------
        bool
            True once a step is accepted (``t``, ``y``, ``f`` advanced); False
            if the step size fell below :func:`min_step` at ``t`` (``message``
            says so; the state is unchanged).
        """

    @abstractmethod
    def dense(self, t: Array) -> Array:
        """Evaluate the last step's continuous extension at times ``t``.

        Parameters
        ----------
        t : ndarray, shape (m,)
            Times in ``[t_old, t]`` of the last accepted step.

        Returns
        -------
        ndarray, shape (m, rows, n)
            The interpolated states.
        """

    def _accept(self, t_new: float, y_new: Array, f_new: Array, h: float, h_next: float) -> None:
        """Advance to an accepted step's end (``h`` its size, ``h_next`` the next to try)."""
        self.t_old, self.y_old = self.t, self.y
        self.t, self.y, self.f = t_new, y_new, f_new
        self._h, self.h_abs = h, h_next
        self.message = ""
