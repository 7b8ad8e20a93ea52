"""Pinocchio's own ``aba``/``rnea`` wrapped as CasADi Callbacks (the ``"pinocchio"`` backend).

Each Callback evaluates Pinocchio numerically (``q`` in angle coordinates,
damping ``b`` applied as in the symbolic backend) and provides exact first
derivatives from ``pin.computeABADerivatives`` / ``pin.computeRNEADerivatives``;
no second derivatives, so IPOPT must use ``hessian_approximation =
"limited-memory"``. The Callbacks must outlive every Function that calls
them: :func:`build_callbacks` returns them for :class:`~youbot_opt.dynamics.Dynamics`
to hold. Details: docs/design.md, "Module notes".

>>> dyn = build_dynamics(model, "pinocchio")  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.dynamics.coordinates import to_pin_configuration

__all__ = ["ForwardDynamicsCallback", "InverseDynamicsCallback", "build_callbacks"]


def _inputs(arg: Any, count: int) -> list[Array]:
    """Copy the first ``count`` raw input buffers into float arrays."""
    return [np.frombuffer(arg[i], dtype=np.float64).copy() for i in range(count)]


def _write(res: Any, i: int, value: Array) -> None:
    """Write ``value`` column-major into output buffer ``i`` unless it was not requested."""
    if res[i] is not None:
        np.frombuffer(res[i], dtype=np.float64)[:] = np.asarray(value).ravel(order="F")


class _PinocchioCallback(ca.Callback):
    """Common plumbing: three (nv, 1) inputs, one (nv, 1) output, a Jacobian Callback."""

    _in_names: tuple[str, str, str] = ("q", "v", "x")
    _out_name: str = "y"

    def __init__(self, name: str, model: pin.Model, damping: Array, opts: dict[str, Any]) -> None:
        ca.Callback.__init__(self)
        self._model = model
        self._data = model.createData()
        self._damping = np.asarray(damping, dtype=float).reshape(-1)
        self._jacobians: list[ca.Callback] = []  # every one CasADi was given stays alive
        self.construct(name, opts)

    def get_n_in(self) -> int:
        return 3

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return self._in_names[i]

    def get_name_out(self, i: int) -> str:
        return self._out_name

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self._model.nv, 1)  # q in angle coordinates

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self._model.nv, 1)

    def has_jacobian(self) -> bool:
        return True

    def get_jacobian(
        self, name: str, inames: Sequence[str], onames: Sequence[str], opts: Mapping[str, Any]
    ) -> ca.Function:
        jacobian = _JacobianCallback(name, self, list(inames), list(onames), dict(opts))
        self._jacobians.append(jacobian)
        return jacobian

    def value(self, q: Array, v: Array, x: Array) -> Array:
        """Numeric output of the Callback (implemented by subclasses)."""
        raise NotImplementedError

    def derivatives(self, q: Array, v: Array, x: Array) -> tuple[Array, Array, Array]:
        """Numeric Jacobians w.r.t. (q, v, x) (implemented by subclasses)."""
        raise NotImplementedError

    def has_eval_buffer(self) -> bool:
        return True

    def pin_inputs(self, arg: Any) -> list[Array]:
        """Return the three raw inputs, q turned from angle coordinates into Pinocchio's (nq,)."""
        q, v, x = _inputs(arg, 3)
        if self._model.nq != self._model.nv:
            q = to_pin_configuration(self._model, q)
        return [q, v, x]

    def eval_buffer(self, arg: Any, res: Any) -> int:
        _write(res, 0, self.value(*self.pin_inputs(arg)))
        return 0


class ForwardDynamicsCallback(_PinocchioCallback):
    """``(q, v, tau) -> a = pin.aba(q, v, tau - b∘v)`` with Pinocchio's analytic Jacobian.

    Parameters
    ----------
    name : str
        Function name, e.g. ``"forward_dynamics"``.
    model : pin.Model
        The robot model (kept by reference).
    damping : ndarray, shape (nv,)
        Viscous damping ``b`` in [N m s/rad]; zeros to disable.
    opts : dict
        CasADi Function options.
    """

    _in_names = ("q", "v", "tau")
    _out_name = "a"

    def value(self, q: Array, v: Array, x: Array) -> Array:
        """Joint accelerations in [rad/s^2] for torques ``x`` in [N m]."""
        return np.array(pin.aba(self._model, self._data, q, v, x - self._damping * v))

    def derivatives(self, q: Array, v: Array, x: Array) -> tuple[Array, Array, Array]:
        """Return ``(da/dq, da/dv, da/dtau)``, each (nv, nv)."""
        da_dq, da_dv, minv = pin.computeABADerivatives(
            self._model, self._data, q, v, x - self._damping * v
        )
        minv = np.array(minv)
        return np.array(da_dq), np.array(da_dv) - minv * self._damping[None, :], minv


class InverseDynamicsCallback(_PinocchioCallback):
    """``(q, v, a) -> tau = pin.rnea(q, v, a) + b∘v`` with Pinocchio's analytic Jacobian.

    Parameters
    ----------
    name : str
        Function name, e.g. ``"inverse_dynamics"``.
    model : pin.Model
        The robot model (kept by reference).
    damping : ndarray, shape (nv,)
        Viscous damping ``b`` in [N m s/rad]; zeros to disable.
    opts : dict
        CasADi Function options.
    """

    _in_names = ("q", "v", "a")
    _out_name = "tau"

    def value(self, q: Array, v: Array, x: Array) -> Array:
        """Joint torques in [N m] for accelerations ``x`` in [rad/s^2]."""
        return np.array(pin.rnea(self._model, self._data, q, v, x)) + self._damping * v

    def derivatives(self, q: Array, v: Array, x: Array) -> tuple[Array, Array, Array]:
        """Return ``(dtau/dq, dtau/dv, dtau/da)``, each (nv, nv)."""
        dtau_dq, dtau_dv, dtau_da = pin.computeRNEADerivatives(self._model, self._data, q, v, x)
        return (
            np.array(dtau_dq),
            np.array(dtau_dv) + np.diag(self._damping),
            np.array(dtau_da),
        )


class _JacobianCallback(ca.Callback):
    """Jacobian of a :class:`_PinocchioCallback`: (q, v, x, y) -> (dy/dq, dy/dv, dy/dx)."""

    def __init__(
        self,
        name: str,
        parent: _PinocchioCallback,
        inames: list[str],
        onames: list[str],
        opts: dict[str, Any],
    ) -> None:
        ca.Callback.__init__(self)
        self._parent = parent
        self._inames = inames
        self._onames = onames
        self.construct(name, opts)

    def get_n_in(self) -> int:
        return 4

    def get_n_out(self) -> int:
        return 3

    def get_name_in(self, i: int) -> str:
        return self._inames[i]

    def get_name_out(self, i: int) -> str:
        return self._onames[i]

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return self._parent.sparsity_in(i) if i < 3 else self._parent.sparsity_out(0)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        nv = self._parent.sparsity_out(0).size1()
        return ca.Sparsity.dense(nv, self._parent.sparsity_in(i).size1())

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg: Any, res: Any) -> int:
        for i, block in enumerate(self._parent.derivatives(*self._parent.pin_inputs(arg))):
            _write(res, i, block)
        return 0


def build_callbacks(
    model: pin.Model, damping: Array
) -> tuple[ForwardDynamicsCallback, InverseDynamicsCallback]:
    """Build the forward and inverse dynamics Callbacks of a model.

    Parameters
    ----------
    model : pin.Model
        The robot model; a private copy is kept so later edits do not leak in.
    damping : ndarray, shape (nv,)
        Viscous damping ``b`` in [N m s/rad] (zeros to disable).

    Returns
    -------
    tuple of (ForwardDynamicsCallback, InverseDynamicsCallback)
        ``"forward_dynamics"`` (q, v, tau) -> a and ``"inverse_dynamics"``
        (q, v, a) -> tau. Keep both objects alive while they are used.
    """
    own = model.copy()
    return (
        ForwardDynamicsCallback("forward_dynamics", own, damping, {}),
        InverseDynamicsCallback("inverse_dynamics", own, damping, {}),
    )
