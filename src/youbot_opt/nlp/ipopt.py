"""IPOPT settings for trajectory solves (:class:`IpoptOptions`).

Defaults are chosen for the study-sized problems: silent, tight tolerance,
MUMPS, and an exact Hessian whenever the dynamics backend is twice
differentiable (``hessian="auto"``; the ``"pinocchio"`` Callback backend only
has first derivatives, so it gets IPOPT's limited-memory quasi-Newton Hessian).

**No default time cap** (``max_cpu_time=None``), by decision. The run time is
already bounded by ``max_iter`` (3000): an IPOPT iteration costs one KKT
factorisation, linear in the number of knots for these banded NLPs (about
1 ms at 50 knots, the base case converging in ~20-40 iterations), so the cap
is reached in seconds at study size and minutes at a few thousand knots,
never an unbounded hang. A CPU-time cap would instead make the *status* of a
seeded solve depend on the machine and its load (a start that converges on
an idle machine would report ``max_time`` on a busy one, or with more
parallel workers), breaking the reproducibility of multistarts and sweeps
that the seeds promise, so it stays an explicit choice
(``IpoptOptions(max_cpu_time=...)``, status
:attr:`~youbot_opt.trajopt.result.SolveStatus.MAX_TIME` when hit).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

from youbot_opt.exceptions import ParameterError

__all__ = ["IpoptOptions", "HessianMode", "WARM_START", "single_threaded_blas", "check_time_limit"]

WARM_START: Mapping[str, Any] = MappingProxyType(
    {
        "warm_start_init_point": "yes",
        "mu_init": 1e-6,
        "warm_start_bound_push": 1e-9,
        "warm_start_bound_frac": 1e-9,
        "warm_start_mult_bound_push": 1e-9,
        "warm_start_slack_bound_push": 1e-9,
        "warm_start_slack_bound_frac": 1e-9,
    }
)
"""IPOPT settings for a primal-dual warm start from a nearby solution."""

HessianMode = Literal["auto", "exact", "limited-memory"]
_HESSIANS: tuple[str, ...] = ("auto", "exact", "limited-memory")


@dataclass(frozen=True, slots=True, kw_only=True)
class IpoptOptions:
    """Options passed to IPOPT through CasADi's ``nlpsol``.

    Attributes
    ----------
    tol : float
        IPOPT's relative convergence tolerance (``tol``), > 0.
    max_iter : int
        Iteration cap (``max_iter``), >= 0. The study's fmincon used 300.
    max_cpu_time : float or None
        CPU-time cap in [s] (``max_cpu_time``); ``None`` (default) for none:
        ``max_iter`` bounds the run deterministically (module docstring).
    print_level : int
        IPOPT verbosity 0 (silent, default) .. 12.
    linear_solver : str
        Sparse linear solver (``"mumps"`` ships with CasADi).
    hessian : {"auto", "exact", "limited-memory"}
        ``"auto"`` uses the exact Hessian when the backend provides second
        derivatives and the limited-memory approximation otherwise.
    mu_strategy : {"adaptive", "monotone"}
        IPOPT barrier-parameter update.
    extra : mapping
        Further IPOPT options by their IPOPT names (e.g. ``{"acceptable_tol": 1e-6}``);
        they override the fields above.
    """

    tol: float = 1e-8
    max_iter: int = 3000
    max_cpu_time: float | None = None
    print_level: int = 0
    linear_solver: str = "mumps"
    hessian: HessianMode = "auto"
    mu_strategy: Literal["adaptive", "monotone"] = "adaptive"
    extra: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (isinstance(self.tol, int | float) and math.isfinite(self.tol) and self.tol > 0):
            raise ParameterError(f"tol must be a finite number > 0, got {self.tol!r}", name="tol")
        if (
            isinstance(self.max_iter, bool)
            or not isinstance(self.max_iter, int)
            or self.max_iter < 0
        ):
            raise ParameterError(
                f"max_iter must be an int >= 0, got {self.max_iter!r}", name="max_iter"
            )
        if self.max_cpu_time is not None and not (
            math.isfinite(self.max_cpu_time) and self.max_cpu_time > 0
        ):
            raise ParameterError(
                f"max_cpu_time must be > 0 [s] or None, got {self.max_cpu_time!r}",
                name="max_cpu_time",
            )
        if not (isinstance(self.print_level, int) and 0 <= self.print_level <= 12):
            raise ParameterError(
                f"print_level must be an int in 0..12, got {self.print_level!r}", name="print_level"
            )
        if self.hessian not in _HESSIANS:
            raise ParameterError(
                f"hessian must be one of {_HESSIANS}, got {self.hessian!r}", name="hessian"
            )
        if self.mu_strategy not in ("adaptive", "monotone"):
            raise ParameterError(
                f"mu_strategy must be 'adaptive' or 'monotone', got {self.mu_strategy!r}",
                name="mu_strategy",
            )
        object.__setattr__(self, "extra", MappingProxyType(dict(self.extra)))

    def exact_hessian(self, available: bool) -> bool:
        """Whether the solve uses the exact Hessian, given backend support.

        Raises
        ------
        ParameterError
            If ``hessian="exact"`` is asked of a backend without second derivatives.
        """
        if self.hessian == "exact" and not available:
            raise ParameterError(
                "hessian='exact' needs second derivatives, which this dynamics backend lacks; "
                "use hessian='limited-memory' (or 'auto') or backend='symbolic'",
                name="hessian",
            )
        return available if self.hessian == "auto" else self.hessian == "exact"

    def to_casadi(self, exact_hessian: bool, *, warm_start: bool = False) -> dict[str, Any]:
        """``nlpsol`` options dict (``ipopt.*`` keys, banner and timing output off).

        Parameters
        ----------
        exact_hessian : bool
            Use the exact Hessian (else IPOPT's limited-memory approximation).
        warm_start : bool
            Add IPOPT's primal-dual warm-start settings (:data:`WARM_START`).
        """
        ipopt: dict[str, Any] = {
            "tol": float(self.tol),
            "max_iter": int(self.max_iter),
            "print_level": int(self.print_level),
            "linear_solver": self.linear_solver,
            "mu_strategy": self.mu_strategy,
            "sb": "yes",
            "hessian_approximation": "exact" if exact_hessian else "limited-memory",
        }
        if self.max_cpu_time is not None:
            ipopt["max_cpu_time"] = float(self.max_cpu_time)
        if warm_start:
            ipopt.update(WARM_START)
        ipopt.update(self.extra)
        return {"ipopt": ipopt, "print_time": False}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary of the fields."""
        return {
            "tol": self.tol,
            "max_iter": self.max_iter,
            "max_cpu_time": self.max_cpu_time,
            "print_level": self.print_level,
            "linear_solver": self.linear_solver,
            "hessian": self.hessian,
            "mu_strategy": self.mu_strategy,
            "extra": dict(self.extra),
        }


def single_threaded_blas() -> None:
    """Keep the OpenBLAS bundled with CasADi's IPOPT to one thread, unless the user chose.

    CasADi loads its own OpenBLAS (for IPOPT's MUMPS) when the first IPOPT
    solver is created, and OpenBLAS reads ``OPENBLAS_NUM_THREADS`` then. Left
    alone it starts one thread per core. On these banded KKT systems the second
    thread buys almost nothing and costs a core: on the 1600-knot study-1
    solve (2 cores) it measured 1.38 s wall / 2.60 s CPU with two threads
    against 1.43 s wall / 1.43 s CPU with one, and a sweep that runs one solver
    per core would oversubscribe the machine. So the solvers call this just
    before creating their first IPOPT instance; it only sets the variable when
    it is unset or empty, so an explicit ``OPENBLAS_NUM_THREADS`` always wins. Libraries
    loaded earlier (numpy's own BLAS) are not affected.
    """
    if not os.environ.get("OPENBLAS_NUM_THREADS"):  # unset or empty: OpenBLAS's default
        os.environ["OPENBLAS_NUM_THREADS"] = "1"


def check_time_limit(value: object, name: str) -> None:
    """Raise :class:`ParameterError` unless ``value`` is None or a finite time > 0 [s].

    Parameters
    ----------
    value : object
        The limit to check, in [s] (None: no limit).
    name : str
        Qualified field name for the message, e.g. ``"ALOptions.max_wall_time"``.
    """
    if value is None:
        return
    if (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value > 0
    ):
        return
    raise ParameterError(
        f"{name} must be None or a finite time > 0 [s], got {value!r}",
        name=name.rsplit(".", 1)[-1],
        value=value,
    )
