"""The :class:`Dynamics` pair of CasADi Functions and :func:`build_dynamics`.

Every backend (``"symbolic"``, ``"pinocchio"``, ``"pinocchio_casadi"``)
yields the same two named Functions, exact inverses of each other and with
the model's viscous damping ``b`` (which Pinocchio's own ``aba``/``rnea``
ignore): ``forward_dynamics`` (q, v, tau) -> a = ABA(q, v, tau - b v) and
``inverse_dynamics`` (q, v, a) -> tau = RNEA(q, v, a) + b v, with ``q`` in
angle coordinates. The backends compared: docs/design.md, "Module notes".

>>> dyn = build_dynamics(load_model("youbot"), "symbolic")  # doctest: +SKIP
"""

from __future__ import annotations

import functools
import importlib.util
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.dynamics.tree import as_pin_model, read_tree
from youbot_opt.exceptions import ParameterError

if TYPE_CHECKING:
    import pinocchio as pin

    from youbot_opt.robot.model import RobotModel

__all__ = ["Dynamics", "build_dynamics", "available_backends", "BACKENDS"]

_LOG = logging.getLogger(__name__)

BACKENDS: tuple[str, ...] = ("symbolic", "pinocchio", "pinocchio_casadi")
"""Every backend name :func:`build_dynamics` knows (not all may be available)."""


def _has_pinocchio_casadi() -> bool:
    try:
        return importlib.util.find_spec("pinocchio.casadi") is not None
    except (ImportError, ValueError):
        return False


def available_backends() -> tuple[str, ...]:
    """Return the backends that can be built in this environment.

    Returns
    -------
    tuple of str
        ``("symbolic", "pinocchio")``, plus ``"pinocchio_casadi"`` when
        ``pinocchio.casadi`` is importable.
    """
    extra = ("pinocchio_casadi",) if _has_pinocchio_casadi() else ()
    return ("symbolic", "pinocchio", *extra)


def _vector(name: str, value: ArrayLike, size: int, meaning: str) -> Array:
    """Return ``value`` as a finite float array of shape (size,), else raise ParameterError.

    A column ``(size, 1)`` or row ``(1, size)`` is accepted and flattened. The
    message names the argument and its ``meaning`` (e.g. "joint velocities in
    [rad/s]"), the expected shape, and the offending shape or entries.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            f"{name} ({meaning}) must be a numeric vector of shape ({size},), got {value!r}",
            name=name,
            value=value,
        ) from exc
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.shape != (size,):
        raise ParameterError(
            f"{name} ({meaning}) must have shape ({size},) or ({size}, 1), got shape {arr.shape}",
            name=name,
            value=arr.shape,
        )
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ParameterError(
            f"{name} ({meaning}) must be finite, got {arr} (non-finite at indices {bad.tolist()})",
            name=name,
            value=arr,
        )
    return arr


@dataclass(frozen=True, slots=True, kw_only=True)
class Dynamics:
    """Forward and inverse dynamics of a fixed-base robot as CasADi Functions.

    Both Functions accept numbers, SX or MX symbols (so they can be called
    inside an NLP and ``.map(N)``-ed over knots) and include the damping below.

    Attributes
    ----------
    backend : str
        ``"symbolic"``, ``"pinocchio"`` or ``"pinocchio_casadi"``.
    nq, nv : int
        Size of the ``q`` input (angle coordinates, so ``nq == nv`` even for
        continuous joints, whose Pinocchio ``nq`` is 2) and of the velocities.
    damping : ndarray, shape (nv,)
        Viscous joint damping ``b`` applied in both Functions, in [N m s/rad]
        (zeros when built with ``damping=False``): ``M a + nle + b∘v = tau``.
    forward_dynamics : casadi.Function
        ``"forward_dynamics"``: (q (nq,), v (nv,), tau (nv,)) -> a (nv,), with
        q in [rad], v in [rad/s], tau in [N m], a in [rad/s^2].
    inverse_dynamics : casadi.Function
        ``"inverse_dynamics"``: (q, v, a) -> tau.
    """

    backend: str
    nq: int
    nv: int
    damping: Array
    forward_dynamics: ca.Function
    inverse_dynamics: ca.Function
    _keepalive: tuple[object, ...] = field(default=(), repr=False, compare=False)

    def forward(self, q: ArrayLike, v: ArrayLike, tau: ArrayLike) -> Array:
        """Evaluate the forward dynamics numerically.

        Parameters
        ----------
        q : array_like, shape (nq,)
            Joint positions in [rad] (or [m] for prismatic joints).
        v : array_like, shape (nv,)
            Joint velocities in [rad/s].
        tau : array_like, shape (nv,)
            Joint torques in [N m].

        Returns
        -------
        ndarray, shape (nv,)
            Joint accelerations in [rad/s^2].

        Raises
        ------
        ParameterError
            If an input has the wrong shape or is not finite.
        """
        return self._evaluate(self.forward_dynamics, q, v, ("tau", tau, "joint torques in [N m]"))

    def inverse(self, q: ArrayLike, v: ArrayLike, a: ArrayLike) -> Array:
        """Evaluate the inverse dynamics numerically.

        Parameters
        ----------
        q : array_like, shape (nq,)
            Joint positions in [rad] (or [m] for prismatic joints).
        v : array_like, shape (nv,)
            Joint velocities in [rad/s].
        a : array_like, shape (nv,)
            Joint accelerations in [rad/s^2].

        Returns
        -------
        ndarray, shape (nv,)
            Joint torques in [N m].

        Raises
        ------
        ParameterError
            If an input has the wrong shape or is not finite.
        """
        return self._evaluate(
            self.inverse_dynamics, q, v, ("a", a, "joint accelerations in [rad/s^2]")
        )

    def _evaluate(
        self, function: ca.Function, q: ArrayLike, v: ArrayLike, x: tuple[str, ArrayLike, str]
    ) -> Array:
        """Evaluate ``function`` at the checked ``(q, v, x)``; ``x`` is (name, value, meaning)."""
        name, value, meaning = x
        args = (
            _vector("q", q, self.nq, "joint positions in [rad] or [m]"),
            _vector("v", v, self.nv, "joint velocities in [rad/s] or [m/s]"),
            _vector(name, value, self.nv, meaning),
        )
        return np.asarray(function(*args), dtype=float).reshape(-1)


_SXDynamics = Callable[[ca.SX, ca.SX, ca.SX], ca.SX]
"""An undamped ``aba(q, v, tau)`` or ``rnea(q, v, a)`` on SX symbols."""


def _damped_functions(
    nv: int, damping: Array, aba: _SXDynamics, rnea: _SXDynamics, options: dict[str, bool]
) -> tuple[ca.Function, ca.Function]:
    """Build ``forward_dynamics`` = aba(q, v, tau - b v) and ``inverse_dynamics`` = rnea + b v."""
    q, v, u = (ca.SX.sym(name, nv) for name in ("q", "v", "u"))
    b = ca.DM(damping)
    forward = ca.Function(
        "forward_dynamics", [q, v, u], [aba(q, v, u - b * v)], ["q", "v", "tau"], ["a"], options
    )
    inverse = ca.Function(
        "inverse_dynamics", [q, v, u], [rnea(q, v, u) + b * v], ["q", "v", "a"], ["tau"], options
    )
    return forward, inverse


def _symbolic(model: pin.Model, damping: Array) -> Dynamics:
    from youbot_opt.dynamics.symbolic import FUNCTION_OPTIONS, build_symbolic_model

    sym = build_symbolic_model(model)
    forward, inverse = _damped_functions(sym.nv, damping, sym.aba, sym.rnea, FUNCTION_OPTIONS)
    return Dynamics(
        backend="symbolic",
        nq=sym.nq,
        nv=sym.nv,
        damping=damping,
        forward_dynamics=forward,
        inverse_dynamics=inverse,
    )


def _pinocchio(model: pin.Model, damping: Array) -> Dynamics:
    from youbot_opt.dynamics.callback import build_callbacks

    pin_model = as_pin_model(model)
    forward, inverse = build_callbacks(pin_model, damping)
    return Dynamics(
        backend="pinocchio",
        nq=pin_model.nv,
        nv=pin_model.nv,
        damping=damping,
        forward_dynamics=forward,
        inverse_dynamics=inverse,
        _keepalive=(forward, inverse),
    )


def _pinocchio_casadi(model: pin.Model, damping: Array) -> Dynamics:
    if not _has_pinocchio_casadi():
        raise ParameterError(
            "backend 'pinocchio_casadi' is unavailable: the PyPI 'pin' wheel is built without "
            "pinocchio.casadi (conda-forge's 'pinocchio' package has it); use backend "
            "'symbolic' (same algorithms transcribed by youbot_opt) or 'pinocchio'",
            name="backend",
            value="pinocchio_casadi",
        )
    import pinocchio.casadi as cpin  # pragma: no cover - absent from the PyPI wheel

    pin_model = as_pin_model(model)  # pragma: no cover
    cmodel = cpin.Model(pin_model)  # pragma: no cover
    cdata = cmodel.createData()  # pragma: no cover
    forward, inverse = _damped_functions(  # pragma: no cover
        pin_model.nv,
        damping,
        functools.partial(cpin.aba, cmodel, cdata),
        functools.partial(cpin.rnea, cmodel, cdata),
        {},
    )
    return Dynamics(  # pragma: no cover
        backend="pinocchio_casadi",
        nq=pin_model.nq,
        nv=pin_model.nv,
        damping=damping,
        forward_dynamics=forward,
        inverse_dynamics=inverse,
        _keepalive=(cmodel, cdata),
    )


def build_dynamics(
    model: RobotModel | pin.Model, backend: str = "symbolic", *, damping: bool = True
) -> Dynamics:
    """Build forward and inverse dynamics CasADi Functions of a fixed-base robot.

    Parameters
    ----------
    model : pin.Model or RobotModel
        The robot (a ``RobotModel`` is unwrapped through its ``model``
        attribute). Joints must be 1-dof revolute, continuous or prismatic;
        a continuous joint's entry of ``q`` is its angle in [rad].
    backend : str, optional
        ``"symbolic"`` (default), ``"pinocchio"`` or ``"pinocchio_casadi"``;
        see :func:`available_backends`.
    damping : bool, optional
        Apply ``model.damping`` (viscous, [N m s/rad]) in both directions
        (default True); False gives Pinocchio's undamped ``aba``/``rnea``.

    Returns
    -------
    Dynamics
        The two Functions and their metadata.

    Raises
    ------
    ParameterError
        For an unknown or unavailable backend (the message lists the available
        ones), a ``model`` that is not a Pinocchio model, or a non-bool ``damping``.
    ModelError
        If the model has a joint type the backends do not support.
    """
    if backend not in BACKENDS:
        raise ParameterError(
            f"unknown dynamics backend {backend!r}; available backends: "
            f"{', '.join(available_backends())}",
            name="backend",
            value=backend,
        )
    if not isinstance(damping, bool | np.bool_):
        raise ParameterError(
            f"damping must be True (apply model.damping) or False, got {damping!r}; "
            "set the coefficients on the model (model.damping) or via load_model(damping=...)",
            name="damping",
            value=damping,
        )
    pin_model = as_pin_model(model)
    tree = read_tree(pin_model)  # validates the joint types for every backend
    b = tree.damping.copy() if damping else np.zeros(tree.nv)
    b.setflags(write=False)
    builders = {
        "symbolic": _symbolic,
        "pinocchio": _pinocchio,
        "pinocchio_casadi": _pinocchio_casadi,
    }
    dynamics = builders[backend](pin_model, b)
    _LOG.debug("built %s dynamics (nv=%d, damping=%s)", backend, tree.nv, b)
    return dynamics
