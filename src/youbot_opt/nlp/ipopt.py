"""IPOPT settings for both optimisers: :class:`IpoptOptions`, single-threaded BLAS.

One options class serves the trajectory optimiser and the IK-path solver. Its
defaults are the trajectory solver's (silent, ``tol`` 1e-8, MUMPS, adaptive
barrier, exact Hessian when the backend has second derivatives, fast KKT
solves, no time cap: ``max_iter`` bounds the run, see docs/design.md);
:meth:`IpoptOptions.for_ikpath` gives the IK-path solver's (``tol`` 1e-12,
``constr_viol_tol`` 1e-11 [m], monotone barrier, IPOPT's own KKT settings).
A time cap gives status ``MAX_TIME``; :func:`bound_relaxation` bounds IPOPT's bound relaxation.

    options = IpoptOptions(max_iter=300)                   # trajectory solves
    options = IpoptOptions.for_ikpath(max_wall_time=5.0)   # IK-path solves, 5 s cap
"""

from __future__ import annotations

import ctypes
import math
import os
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Literal, TypeAlias, TypedDict, Unpack

import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._checks import check_time_limit
from youbot_opt._files import file_kind
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError

if TYPE_CHECKING:  # casadi stays unimported until a solver is built (the CLI parser reads this)
    import casadi as ca

__all__ = [
    "IpoptOptions",
    "HessianMode",
    "MuStrategy",
    "IpoptValue",
    "WARM_START",
    "FAST_KKT",
    "LINEAR_SOLVERS",
    "RUNTIME_SOLVERS",
    "check_linear_solver",
    "single_threaded_blas",
    "BOUND_RELAX_FACTOR",
    "RELAX_SHARE",
    "bound_relaxation",
]

IpoptValue = str | int | float
"""Type of an IPOPT option's value (IPOPT options are strings, integers or reals)."""

WARM_START: Mapping[str, IpoptValue] = MappingProxyType(
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

FAST_KKT: Mapping[str, IpoptValue] = MappingProxyType(
    {
        "fast_step_computation": "yes",
        "min_refinement_steps": 0,
        "mumps_scaling": 0,
        "mumps_permuting_scaling": 0,
        "mumps_pivot_order": 0,
    }
)
"""IPOPT settings of :attr:`IpoptOptions.fast_kkt`: no residual check or iterative
refinement of the KKT solves unless IPOPT asks for it, no MUMPS scaling, MUMPS's
AMD fill-reducing ordering instead of its automatic choice
(``benchmarks/bench_trajopt.py --side-by-side --levers`` measures each; docs/design.md,
"IPOPT: one options class")."""

BOUND_RELAX_FACTOR = 1e-8
"""IPOPT's default ``bound_relax_factor``: while it iterates, IPOPT moves every bound
outward by this times ``max(1, |bound|)``, and (IPOPT >= 3.14, ``honor_original_bounds``
no) returns a point of the relaxed box."""

RELAX_SHARE = 0.1
"""Largest share of a solution's feasibility tolerance IPOPT's bound relaxation may
take (:func:`bound_relaxation`)."""

RUNTIME_SOLVERS: Mapping[str, tuple[str, str, str]] = MappingProxyType(
    {
        "ma27": ("hsllib", "libhsl.so", "ma27ad"),
        "ma57": ("hsllib", "libhsl.so", "ma57ad"),
        "ma77": ("hsllib", "libhsl.so", "ma77_open_d"),
        "ma86": ("hsllib", "libhsl.so", "ma86_analyse_d"),
        "ma97": ("hsllib", "libhsl.so", "ma97_analyse_d"),
        "pardiso": ("pardisolib", "libpardiso.so", "pardiso_ipopt_newinterface"),
    }
)
"""Linear solvers that CasADi's IPOPT loads from a shared library when a solver is
created: name -> (IPOPT's library option, its default library, a routine IPOPT
looks up in it). HSL's solvers come in the ``libhsl.so`` built by coin-or's
ThirdParty-HSL from the HSL sources (licensed by STFC, free for academic use);
Pardiso from pardiso-project.org. Neither ships with CasADi or on PyPI."""

LINEAR_SOLVERS: tuple[str, ...] = ("mumps", "spral", *RUNTIME_SOLVERS)
"""Values of :attr:`IpoptOptions.linear_solver` that CasADi's IPOPT (3.14) accepts:
MUMPS and SPRAL are built in, the others are loaded at run time
(:data:`RUNTIME_SOLVERS`)."""

HessianMode = Literal["auto", "exact", "limited-memory"]

NlpsolOption: TypeAlias = (
    "bool | int | float | str | ca.Function"
    " | Sequence[NlpsolOption] | Mapping[str, NlpsolOption] | None"
)
"""A value in CasADi's ``nlpsol`` options dict (nested dicts for a plugin's own options)."""

MuStrategy = Literal["adaptive", "monotone"]
_HESSIANS: tuple[str, ...] = ("auto", "exact", "limited-memory")


class _OtherFields(TypedDict, total=False):
    """The :class:`IpoptOptions` fields :meth:`IpoptOptions.for_ikpath` passes on unchanged."""

    max_iter: int
    max_cpu_time: float | None
    max_wall_time: float | None
    print_level: int
    linear_solver: str
    linear_solver_library: str | None
    hessian: HessianMode
    extra: Mapping[str, IpoptValue]


@dataclass(frozen=True, slots=True, kw_only=True)
class IpoptOptions:
    """Options passed to IPOPT through CasADi's ``nlpsol`` (both optimisers).

    Attributes
    ----------
    tol : float
        IPOPT's (scaled) overall optimality tolerance (``tol``), > 0.
    constr_viol_tol : float or None
        Largest accepted constraint violation (``constr_viol_tol``), in the
        unit of the constraint rows ([m] for the IK path), > 0; ``None``
        (default) leaves IPOPT's own (1e-4). The IK-path solver needs it set
        (:meth:`for_ikpath`): it is that solver's success criterion.
    max_iter : int
        Iteration cap (``max_iter``), >= 0. The study's fmincon used 300.
    max_cpu_time : float or None
        CPU-time cap in [s] (``max_cpu_time``); ``None`` (default) for none:
        ``max_iter`` bounds the run deterministically.
    max_wall_time : float or None
        Wall-clock cap of one solve in [s] (``max_wall_time``); ``None``
        (default) for none.
    print_level : int
        IPOPT verbosity 0 (silent, default) .. 12.
    linear_solver : str
        Sparse linear solver of IPOPT's KKT systems, one of
        :data:`LINEAR_SOLVERS`. ``"mumps"`` (default) and ``"spral"`` ship with
        CasADi; HSL's ``"ma27"``, ``"ma57"``, ``"ma77"``, ``"ma86"``, ``"ma97"``
        and ``"pardiso"`` are loaded from :attr:`linear_solver_library` when a
        solver is created (:func:`check_linear_solver` says so clearly if
        that library is missing).
    linear_solver_library : str or None
        Path (or name on the loader's search path) of the library holding a
        run-time-loaded solver: IPOPT's ``hsllib`` (HSL's ``libhsl.so``) or
        ``pardisolib``. ``None`` (default) leaves IPOPT's default name
        (:data:`RUNTIME_SOLVERS`). Only with such a solver.
    hessian : {"auto", "exact", "limited-memory"}
        ``"auto"`` uses the exact Hessian when the backend provides second
        derivatives and the limited-memory approximation otherwise.
    mu_strategy : {"adaptive", "monotone"}
        IPOPT barrier-parameter update.
    fast_kkt : bool
        Solve IPOPT's KKT systems the fast way (:data:`FAST_KKT`; default
        True): it changes how each Newton step is computed, not the problem
        or its optimum. :meth:`to_dict` lists it only when False, so the
        dictionary of the defaults is the one earlier versions wrote.
    extra : mapping
        Further IPOPT options by their IPOPT names (e.g. ``{"acceptable_tol": 1e-6}``);
        they override the fields above and the solver's own settings.
    """

    tol: float = 1e-8
    constr_viol_tol: float | None = None
    max_iter: int = 3000
    max_cpu_time: float | None = None
    max_wall_time: float | None = None
    print_level: int = 0
    linear_solver: str = "mumps"
    linear_solver_library: str | None = None
    hessian: HessianMode = "auto"
    mu_strategy: MuStrategy = "adaptive"
    fast_kkt: bool = True
    extra: Mapping[str, IpoptValue] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (isinstance(self.tol, int | float) and math.isfinite(self.tol) and self.tol > 0):
            raise ParameterError(f"tol must be a finite number > 0, got {self.tol!r}", name="tol")
        if self.constr_viol_tol is not None and not (
            isinstance(self.constr_viol_tol, int | float)
            and not isinstance(self.constr_viol_tol, bool)
            and math.isfinite(self.constr_viol_tol)
            and self.constr_viol_tol > 0
        ):
            raise ParameterError(
                f"constr_viol_tol must be None or a finite number > 0, got "
                f"{self.constr_viol_tol!r}",
                name="constr_viol_tol",
            )
        if (
            isinstance(self.max_iter, bool)
            or not isinstance(self.max_iter, int)
            or self.max_iter < 0
        ):
            raise ParameterError(
                f"max_iter must be an int >= 0, got {self.max_iter!r}", name="max_iter"
            )
        check_time_limit(self.max_cpu_time, "max_cpu_time")
        check_time_limit(self.max_wall_time, "IpoptOptions.max_wall_time")
        if not (isinstance(self.print_level, int) and 0 <= self.print_level <= 12):
            raise ParameterError(
                f"print_level must be an int in 0..12, got {self.print_level!r}", name="print_level"
            )
        if self.linear_solver not in LINEAR_SOLVERS:
            raise ParameterError(
                f"linear_solver must be one of {LINEAR_SOLVERS} (the solvers CasADi's IPOPT "
                f"accepts), got {self.linear_solver!r}",
                name="linear_solver",
                value=self.linear_solver,
            )
        if self.linear_solver_library is not None:
            if self.linear_solver not in RUNTIME_SOLVERS:
                raise ParameterError(
                    f"linear_solver_library={self.linear_solver_library!r} is only used by the "
                    f"solvers IPOPT loads at run time {tuple(RUNTIME_SOLVERS)}; linear_solver is "
                    f"{self.linear_solver!r}",
                    name="linear_solver_library",
                    value=self.linear_solver_library,
                )
            if not isinstance(self.linear_solver_library, str) or not self.linear_solver_library:
                raise ParameterError(
                    "linear_solver_library must be a non-empty path or library name, got "
                    f"{self.linear_solver_library!r}",
                    name="linear_solver_library",
                )
            _check_library_path(self.linear_solver_library)
        if self.hessian not in _HESSIANS:
            raise ParameterError(
                f"hessian must be one of {_HESSIANS}, got {self.hessian!r}", name="hessian"
            )
        if self.mu_strategy not in ("adaptive", "monotone"):
            raise ParameterError(
                f"mu_strategy must be 'adaptive' or 'monotone', got {self.mu_strategy!r}",
                name="mu_strategy",
            )
        if not isinstance(self.fast_kkt, bool):
            raise ParameterError(
                f"fast_kkt must be True or False, got {self.fast_kkt!r}", name="fast_kkt"
            )
        object.__setattr__(self, "extra", dict(self.extra))

    @classmethod
    def for_ikpath(
        cls,
        *,
        tol: float = 1e-12,
        constr_viol_tol: float = 1e-11,
        mu_strategy: MuStrategy = "monotone",
        fast_kkt: bool = False,
        **changes: Unpack[_OtherFields],
    ) -> IpoptOptions:
        """Return the IK-path solver's defaults, with ``changes``.

        The IK-path NLP is small and well scaled and is solved to rounding
        level: ``tol`` 1e-12, ``constr_viol_tol`` 1e-11 [m] (the tip's
        accepted distance from each target) and IPOPT's monotone barrier
        update, with IPOPT's own KKT settings (iterative refinement, MUMPS
        scaling). Other fields keep the class defaults.

        Parameters
        ----------
        tol : float
            IPOPT's optimality tolerance.
        constr_viol_tol : float
            Largest accepted target miss in [m].
        mu_strategy : {"adaptive", "monotone"}
            IPOPT barrier-parameter update.
        fast_kkt : bool
            Use :data:`FAST_KKT` (off: the IK path is solved to rounding level).
        **changes
            Any other field (``max_iter``, ``max_wall_time``, ``extra``, ...).

        Returns
        -------
        IpoptOptions
            The options.
        """
        return cls(
            tol=tol,
            constr_viol_tol=constr_viol_tol,
            mu_strategy=mu_strategy,
            fast_kkt=fast_kkt,
            **changes,
        )

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

    def to_casadi(
        self,
        exact_hessian: bool,
        *,
        warm_start: bool = False,
        solver_settings: Mapping[str, IpoptValue] | None = None,
    ) -> dict[str, NlpsolOption]:
        """``nlpsol`` options dict (``ipopt.*`` keys, banner and timing output off).

        Parameters
        ----------
        exact_hessian : bool
            Use the exact Hessian (else IPOPT's limited-memory approximation).
        warm_start : bool
            Add IPOPT's primal-dual warm-start settings (:data:`WARM_START`).
        solver_settings : mapping, optional
            IPOPT options a solver sets for its own NLP (e.g. how bounds are
            treated); :attr:`extra` overrides them.

        Returns
        -------
        dict
            ``{"ipopt": {...}, "print_time": False}``.

        Raises
        ------
        ParameterError
            If :attr:`linear_solver` is loaded at run time and its library
            cannot be loaded or lacks the solver (:func:`check_linear_solver`).
        """
        library = check_linear_solver(self)
        ipopt: dict[str, IpoptValue] = {
            "tol": float(self.tol),
            "max_iter": int(self.max_iter),
            "print_level": int(self.print_level),
            "linear_solver": self.linear_solver,
            "mu_strategy": self.mu_strategy,
            "sb": "yes",
            "hessian_approximation": "exact" if exact_hessian else "limited-memory",
        }
        if self.fast_kkt:
            ipopt.update(
                (k, v)
                for k, v in FAST_KKT.items()
                if self.linear_solver == "mumps" or not k.startswith("mumps_")
            )
        if library is not None:
            ipopt[RUNTIME_SOLVERS[self.linear_solver][0]] = library
        if self.constr_viol_tol is not None:
            ipopt["constr_viol_tol"] = float(self.constr_viol_tol)
        if self.max_cpu_time is not None:
            ipopt["max_cpu_time"] = float(self.max_cpu_time)
        if self.max_wall_time is not None:
            ipopt["max_wall_time"] = float(self.max_wall_time)
        if warm_start:
            ipopt.update(WARM_START)
        if solver_settings is not None:
            ipopt.update(solver_settings)
        ipopt.update(self.extra)
        return {"ipopt": ipopt, "print_time": False}

    def to_dict(self) -> JSONDict:
        """JSON-ready dictionary of the fields.

        ``constr_viol_tol``, ``max_wall_time`` and ``linear_solver_library``
        appear only when set, and
        ``fast_kkt`` only when False, so
        the dictionary (stored in result files and sweep manifests) of options
        that do not use them is the one earlier versions wrote.
        """
        out: JSONDict = {
            "tol": self.tol,
            "max_iter": self.max_iter,
            "max_cpu_time": self.max_cpu_time,
            "print_level": self.print_level,
            "linear_solver": self.linear_solver,
            "hessian": self.hessian,
            "mu_strategy": self.mu_strategy,
            "extra": dict(self.extra),
        }
        if self.constr_viol_tol is not None:
            out["constr_viol_tol"] = self.constr_viol_tol
        if self.max_wall_time is not None:
            out["max_wall_time"] = self.max_wall_time
        if self.linear_solver_library is not None:
            out["linear_solver_library"] = self.linear_solver_library
        if not self.fast_kkt:
            out["fast_kkt"] = False
        return out


def bound_relaxation(
    bounds: Sequence[ArrayLike], feasibility_tol: float
) -> Mapping[str, IpoptValue]:
    """IPOPT's ``bound_relax_factor`` for bounds this large, or ``{}`` for IPOPT's default.

    IPOPT relaxes a bound ``b`` by :data:`BOUND_RELAX_FACTOR` ``* max(1, |b|)``
    and returns a point of the relaxed box, so a variable at a large bound can
    end farther outside it than the tolerance the solution is then checked with
    (a UR5 torque at its 150 N m bound: 1.5e-6 N m of relaxation, 1.3e-6 N m
    past the bound, over the trajectory solver's 1e-6: a false constraint
    violation). The factor returned keeps the relaxation of the largest finite
    bound within :data:`RELAX_SHARE` of ``feasibility_tol``; where IPOPT's
    default already does (every bound of the study's youBot: at most 9.5), it
    returns ``{}`` and IPOPT's default stays, so those solves are unchanged bit
    for bit. Measured, and why neither ``honor_original_bounds=yes`` (the
    projection breaks the dynamics defects by up to 4.5e-6 on stiff arms) nor a
    factor of 0 for all (the study's Radau figure 8.094584 moves by 2.3e-8, out
    of its pinned 5e-7): docs/design.md, "IPOPT: one options class".

    Parameters
    ----------
    bounds : sequence of array_like
        The NLP's bound vectors (``lbx``, ``ubx``, ``lbg``, ``ubg``); infinite
        entries are ignored.
    feasibility_tol : float
        Largest violation a solution may have, > 0.

    Returns
    -------
    mapping
        ``{"bound_relax_factor": f}`` with ``f < BOUND_RELAX_FACTOR``, or ``{}``.
    """
    largest = 1.0
    for b in bounds:
        values = np.abs(np.asarray(b, dtype=float))
        largest = max(largest, float(np.max(values[np.isfinite(values)], initial=0.0)))
    allowed = RELAX_SHARE * float(feasibility_tol)
    if BOUND_RELAX_FACTOR * largest <= allowed:
        return {}
    return {"bound_relax_factor": allowed / largest}


def check_linear_solver(options: IpoptOptions) -> str | None:
    """Check that IPOPT will find the library of a run-time-loaded linear solver.

    IPOPT itself reports a missing library only as ``Invalid_Option`` (or a
    CasADi error) once the solve has started; this names the library and the
    routine instead. MUMPS and SPRAL need nothing.

    Parameters
    ----------
    options : IpoptOptions
        Its :attr:`~IpoptOptions.linear_solver`, its
        :attr:`~IpoptOptions.linear_solver_library`, or the library option
        (``hsllib`` / ``pardisolib``) in its ``extra``, which wins.

    Returns
    -------
    str or None
        The library IPOPT is to load (``None`` for a built-in solver, or when
        ``extra`` already names it).

    Raises
    ------
    ParameterError
        If the library cannot be loaded, or exports no routine of the solver.
    """
    spec = RUNTIME_SOLVERS.get(options.linear_solver)
    if spec is None:
        return None
    option, default, routine = spec
    given = options.extra.get(option)
    library = str(given if given is not None else (options.linear_solver_library or default))
    name = options.linear_solver
    where = "HSL" if option == "hsllib" else "Pardiso"
    _check_library_path(library)  # from extra too: dlopen of a FIFO never returns
    try:
        handle = ctypes.CDLL(library)
    except OSError as exc:
        raise ParameterError(
            f"linear_solver={name!r} is loaded by IPOPT at run time from the {where} library "
            f"{library!r}, which cannot be loaded ({exc}); build it (coin-or ThirdParty-HSL "
            "for HSL's solvers) and pass linear_solver_library='/path/to/the/library', or use "
            "linear_solver='mumps' (built in)",
            name="linear_solver_library",
            value=library,
        ) from exc
    variants = (routine, routine + "_", routine.upper(), routine.upper() + "_")
    if not any(hasattr(handle, symbol) for symbol in variants):
        raise ParameterError(
            f"the library {library!r} has no {name.upper()} (routine {routine!r} not found): "
            f"it is not a {where} library with linear_solver={name!r}",
            name="linear_solver_library",
            value=library,
        )
    return None if given is not None else library


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


def _check_library_path(library: str) -> None:
    """Refuse a library path that exists but is no regular file (a FIFO would block dlopen).

    A bare library name (no folder) is left to the dynamic loader's search path.
    """
    if os.sep not in library:
        return
    try:
        mode = os.stat(library).st_mode
    except OSError:
        return  # a missing file: IPOPT's own error names it
    if not stat.S_ISREG(mode):
        raise ParameterError(
            f"linear_solver_library {library!r} is not a regular file but {file_kind(mode)} "
            "(a shared library is a regular file); not opened",
            name="linear_solver_library",
            value=library,
        )
