"""The implicit Runge-Kutta method Radau IIA of order 5, with error control.

Owns the stiff integrator of the certificate's simulations
(:mod:`youbot_opt.trajopt.simulate`): SciPy's ``solve_ivp(method="Radau")``
(Hairer and Wanner, *Solving ODEs II*, IV.8) step for step, without importing
``scipy.integrate``: same tableau, Newton iteration on the collocation system
with the real and complex factorisations reused while it converges, embedded
3rd-order error estimate and predictive step-size control. The state is a
stack of rows, each held to the tolerances; the Jacobian is block-diagonal
(the caller's blocks), so :class:`Radau5` factors the blocks, not the whole.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from youbot_opt._typing import Array
from youbot_opt.dynamics.stepper import (
    MAX_FACTOR,
    MIN_FACTOR,
    SAFETY,
    TOO_SMALL_STEP,
    Rhs,
    Stepper,
    min_step,
    next_step_size,
    trial_step,
)

__all__ = ["Jacobian", "Radau5"]

Jacobian = Callable[[float, Array], Array]
"""``jac(t, y) -> blocks``: the diagonal blocks, shape (B, nb, nb), of ``df/dy``
over the flattened state (``B nb = rows n``); the rest of ``df/dy`` is zero."""

_S6 = 6.0**0.5
_C = np.array([(4.0 - _S6) / 10.0, (4.0 + _S6) / 10.0, 1.0])  # collocation nodes
_E = np.array([-13.0 - 7.0 * _S6, -13.0 + 7.0 * _S6, -1.0]) / 3.0  # error estimate
# Eigenvalues of the inverse Butcher matrix (one real, one complex pair), as SciPy's.
_MU_REAL = 3.0 + 3.0 ** (2.0 / 3.0) - 3.0 ** (1.0 / 3.0)
_MU_COMPLEX = (
    3.0 + 0.5 * (3.0 ** (1.0 / 3.0) - 3.0 ** (2.0 / 3.0))
    - 0.5j * (3.0 ** (5.0 / 6.0) + 3.0 ** (7.0 / 6.0))
)  # fmt: skip
# The transformation to the eigenbasis (A = T L T^-1) and back, SciPy's digits.
_T = np.array([
    [0.09443876248897524, -0.14125529502095421, 0.03002919410514742],
    [0.25021312296533332, 0.20412935229379994, -0.38294211275726192],
    [1.0, 1.0, 0.0],
])  # fmt: skip
_TI = np.array([
    [4.17871859155190428, 0.32768282076106237, 0.52337644549944951],
    [-4.17871859155190428, -0.32768282076106237, 0.47662355450055044],
    [0.50287263494578682, -2.57192694985560522, 0.59603920482822492],
])  # fmt: skip
_TI_REAL = _TI[0]
_TI_COMPLEX = _TI[1] + 1j * _TI[2]  # applied as its real and imaginary parts (see _newton)
# The dense output's coefficients (y = y_old + Z^T P [x, x^2, x^3]).
_P = np.array([
    [13.0 / 3.0 + 7.0 * _S6 / 3.0, -23.0 / 3.0 - 22.0 * _S6 / 3.0, 10.0 / 3.0 + 5.0 * _S6],
    [13.0 / 3.0 - 7.0 * _S6 / 3.0, -23.0 / 3.0 + 22.0 * _S6 / 3.0, 10.0 / 3.0 - 5.0 * _S6],
    [1.0 / 3.0, -8.0 / 3.0, 10.0 / 3.0],
])  # fmt: skip
for _array in (_C, _E, _T, _TI, _TI_REAL, _TI_COMPLEX, _P):
    _array.setflags(write=False)

_NEWTON_MAXITER = 6  # Newton iterations of one collocation solve
_EPS = float(np.finfo(float).eps)
_SAME_H = 1e-6  # relative change of h below which a factorisation is reused (see step)


def _predict_factor(
    h_abs: float, h_abs_old: float | None, error_norm: float, error_norm_old: float | None
) -> float:
    """SciPy's ``predict_factor``: Gustafsson's predictive controller (Hairer II, IV.8)."""
    if error_norm_old is None or h_abs_old is None or error_norm == 0.0:
        multiplier = 1.0
    else:
        multiplier = h_abs / h_abs_old * (error_norm_old / error_norm) ** 0.25
    with np.errstate(divide="ignore"):
        return float(min(1.0, multiplier) * np.float64(error_norm) ** -0.25)


class Radau5(Stepper):
    """Radau IIA (order 5) integration of a stack of rows, one accepted step at a time.

    A :class:`~youbot_opt.dynamics.stepper.Stepper` that also holds the
    Jacobian blocks and their factorisations. :meth:`step` takes one accepted
    step towards ``t_bound`` without passing it; :meth:`dense` evaluates the
    last step's collocation polynomial. Errors (and Newton increments) are
    measured per row (RMS over the row) and the largest row's decides: with one
    row and one block this is SciPy's Radau.

    Two departures from SciPy, both for stepping from knot to knot: a step cut
    to end on ``t_bound`` refactors the Newton matrices if ``h`` changed by more
    than 1e-6 relative (SciPy reuses the old ones on its last step), and after a
    cut step the next step may again be as long as the one before the cut (as
    :class:`~youbot_opt.dynamics.dop853.Dop853`).

    Parameters
    ----------
    fun : callable
        Right-hand side ``f(t, y)``, shape (rows, n) in and out (see
        :class:`~youbot_opt.dynamics.stepper.Stepper`).
    jac : callable
        ``jac(t, y)``: the diagonal blocks of ``df/dy`` over the flattened
        state, shape (B, nb, nb) with ``B nb = rows n`` (see :data:`Jacobian`).
    t0, y0, rtol, atol, t_bound, first_step, f0
        As :class:`~youbot_opt.dynamics.stepper.Stepper` (the first step by
        default SciPy's choice: Hairer's, for the 3rd-order error estimate).

    Attributes
    ----------
    njev, nlu : int
        Evaluations of ``jac``, and factorisations (real and complex counted
        apart, as SciPy), so far; the others are the
        :class:`~youbot_opt.dynamics.stepper.Stepper`'s.
    """

    error_order = 3

    def __init__(
        self,
        fun: Rhs,
        jac: Jacobian,
        t0: float,
        y0: Array,
        *,
        rtol: float,
        atol: float,
        t_bound: float,
        first_step: float | None = None,
        f0: Array | None = None,
    ) -> None:
        super().__init__(
            fun, t0, y0, rtol=rtol, atol=atol, t_bound=t_bound, first_step=first_step, f0=f0
        )
        self.jac = jac
        self.njev = self.nlu = 0
        self.h_abs_old: float | None = None
        self.error_norm_old: float | None = None
        self.newton_tol = max(10.0 * _EPS / self.rtol, min(0.03, self.rtol**0.5))
        self._J = self._jacobian(self.t, self.y)
        self._current_jac = True
        self._inv_real: Array | None = None  # (mu_real / h - J)^-1, block by block
        self._inv_complex: NDArray[np.complex128] | None = None
        self._lu_h = 0.0  # the h the inverses were made for
        self._Q: Array | None = None  # the last step's dense output, shape (3, rows n)

    # ------------------------------------------------------------ pieces
    def _jacobian(self, t: float, y: Array) -> Array:
        self.njev += 1
        blocks = np.array(self.jac(t, y), dtype=float)
        if blocks.ndim != 3 or blocks.shape[1] != blocks.shape[2]:
            raise ValueError(f"jac must return blocks of shape (B, nb, nb), got {blocks.shape}")
        if blocks.shape[0] * blocks.shape[1] != y.size:
            raise ValueError(f"jac's blocks {blocks.shape} do not cover a state of {y.size}")
        return blocks

    def _factor(self, h: float) -> None:
        """Invert the Newton matrices ``mu / h - J`` of every block (batched LAPACK)."""
        eye = np.eye(self._J.shape[1])
        self._inv_real = np.linalg.inv((_MU_REAL / h) * eye - self._J).astype(float, copy=False)
        self._inv_complex = np.linalg.inv((_MU_COMPLEX / h) * eye - self._J)
        self._lu_h = h
        self.nlu += 2

    @staticmethod
    def _solve(inverse: NDArray[np.inexact], b: NDArray[np.inexact]) -> NDArray[np.inexact]:
        """``inverse`` (blocks) times the flat vector ``b``."""
        nb = inverse.shape[1]
        return np.matmul(inverse, b.reshape(-1, nb, 1)).reshape(b.shape)

    def _norm(self, x: Array) -> float:
        """Return the largest row's RMS of ``x`` (shape (k, rows n) or (rows n,), scaled)."""
        rows, n = self.y.shape
        if rows == 1:
            flat = x.reshape(-1)
            return float(np.sqrt(np.dot(flat, flat) / flat.size))
        stack = x.reshape(-1, rows, n)
        squares = np.einsum("krn,krn->r", stack, stack)
        return float(np.sqrt(np.max(squares) / (stack.shape[0] * n)))

    def _eval(self, t: float, y_flat: Array) -> Array:
        self.nfev += 1
        return np.asarray(self.fun(t, y_flat.reshape(self.y.shape)), dtype=float).reshape(-1)

    def _newton(
        self, t: float, y: Array, h: float, Z0: Array, scale: Array
    ) -> tuple[bool, int, Array, float | None]:
        """SciPy's ``solve_collocation_system``: converged, iterations, Z, rate."""
        assert self._inv_real is not None and self._inv_complex is not None
        m_real, m_complex = _MU_REAL / h, _MU_COMPLEX / h
        W = _TI.dot(Z0)
        Z = Z0
        F = np.empty_like(Z0)
        dW = np.empty_like(W)
        ch = h * _C
        dW_norm_old: float | None = None
        rate: float | None = None
        converged = False
        k = 0
        for k in range(_NEWTON_MAXITER):
            for i in range(3):
                F[i] = self._eval(t + ch[i], y + Z[i])
            if not np.all(np.isfinite(F)):
                break
            TF = _TI.dot(F)  # real products: NumPy's complex-by-real dot is 100x slower
            f_real = TF[0] - m_real * W[0]
            f_complex = (TF[1] + 1j * TF[2]) - m_complex * (W[1] + 1j * W[2])
            dW[0] = self._solve(self._inv_real, f_real)
            dW_complex = self._solve(self._inv_complex, f_complex)
            dW[1] = dW_complex.real
            dW[2] = dW_complex.imag
            dW_norm = self._norm(dW / scale)
            if dW_norm_old is not None:
                rate = dW_norm / dW_norm_old
            if rate is not None and (
                rate >= 1.0
                or rate ** (_NEWTON_MAXITER - k) / (1.0 - rate) * dW_norm > self.newton_tol
            ):
                break
            W += dW
            Z = _T.dot(W)
            if dW_norm == 0.0 or (
                rate is not None and rate / (1.0 - rate) * dW_norm < self.newton_tol
            ):
                converged = True
                break
            dW_norm_old = dW_norm
        return converged, k + 1, Z, rate

    # ------------------------------------------------------------ stepping
    def refresh(self) -> None:
        """Re-evaluate ``f = fun(t, y)`` after ``fun`` changed at the current time.

        The Jacobian and its factorisations are kept (marked stale: a Newton
        failure re-evaluates the Jacobian); the last step's dense output stays
        the step's.
        """
        super().refresh()
        self._current_jac = False

    def step(self, t_bound: float) -> bool:
        """Take one accepted step towards ``t_bound``, at most to ``t_bound``.

        See :meth:`Stepper.step <youbot_opt.dynamics.stepper.Stepper.step>`.
        """
        t = self.t
        y = self.y.reshape(-1)
        f = self.f.reshape(-1)
        atol, rtol = self.atol, self.rtol
        smallest = min_step(t)
        h_abs_old, error_norm_old = self.h_abs_old, self.error_norm_old
        h_abs = self.h_abs
        if h_abs < smallest:
            h_abs, h_abs_old, error_norm_old = smallest, None, None
        wanted, rejected = h_abs, False
        while True:
            if not h_abs >= smallest:  # NaN-safe: a NaN size fails too
                self.message = TOO_SMALL_STEP
                return False
            t_new, h, cut = trial_step(t, h_abs, t_bound)
            h_abs = abs(h)
            if self._Q is None:
                Z0 = np.zeros((3, y.size))
            else:
                Z0 = self._dense_flat(t + h * _C) - y
            scale = atol + np.abs(y) * rtol
            converged = False
            n_iter, Z, rate = 0, Z0, None
            while not converged:
                if self._inv_real is None or abs(h - self._lu_h) > _SAME_H * abs(self._lu_h):
                    self._factor(h)
                converged, n_iter, Z, rate = self._newton(t, y, h, Z0, scale)
                if not converged:
                    if self._current_jac:
                        break
                    self._J = self._jacobian(t, self.y)
                    self._current_jac = True
                    self._inv_real = self._inv_complex = None
            if not converged:
                h_abs *= 0.5
                self._inv_real = self._inv_complex = None
                continue
            assert self._inv_real is not None
            y_new = y + Z[-1]
            ZE = _E.dot(Z) / h
            error = self._solve(self._inv_real, f + ZE)
            scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol
            with np.errstate(all="ignore"):
                error_norm = self._norm(error / scale)
            safety = SAFETY * (2 * _NEWTON_MAXITER + 1) / (2 * _NEWTON_MAXITER + n_iter)
            if rejected and error_norm > 1.0:
                error = self._solve(self._inv_real, self._eval(t, y + error) + ZE)
                with np.errstate(all="ignore"):
                    error_norm = self._norm(error / scale)
            if error_norm <= 1.0:
                break
            if np.isfinite(error_norm):
                factor = _predict_factor(h_abs, h_abs_old, error_norm, error_norm_old)
            else:
                factor = MIN_FACTOR  # a state that is not finite: rejected, then failed
            h_abs *= max(MIN_FACTOR, safety * factor)
            self._inv_real = self._inv_complex = None
            rejected = True

        recompute_jac = n_iter > 2 and rate is not None and rate > 1e-3
        factor = _predict_factor(h_abs, h_abs_old, error_norm, error_norm_old)
        factor = min(MAX_FACTOR, safety * factor)
        if not recompute_jac and factor < 1.2:
            factor = 1.0
        else:
            self._inv_real = self._inv_complex = None
        h_next = next_step_size(h_abs, factor, wanted=wanted, cut=cut, rejected=rejected)
        f_new = self._eval(t_new, y_new)
        y_new_rows = y_new.reshape(self.y.shape)
        if recompute_jac:
            self._J = self._jacobian(t_new, y_new_rows)
            self._current_jac = True
        else:
            self._current_jac = False
        self.h_abs_old = self.h_abs
        self.error_norm_old = error_norm
        self._accept(t_new, y_new_rows, f_new.reshape(self.y.shape), h, h_next)
        self._Q = _P.T.dot(Z)
        return True

    def _dense_flat(self, t: Array) -> Array:
        """Return the last step's polynomial at times ``t`` as flat rows, shape (m, rows n)."""
        assert self._Q is not None
        x = (np.asarray(t, dtype=float) - self.t_old) / self._h
        powers = np.stack([x, x * x, x * x * x], axis=1)
        return np.dot(powers, self._Q) + self.y_old.reshape(-1)

    def dense(self, t: Array) -> Array:
        """Evaluate the last step's collocation polynomial (3rd degree) at times ``t``.

        See :meth:`Stepper.dense <youbot_opt.dynamics.stepper.Stepper.dense>`.
        """
        if self._Q is None:
            raise RuntimeError("no step taken yet")
        rows, n = self.y.shape
        return self._dense_flat(t).reshape(-1, rows, n)
