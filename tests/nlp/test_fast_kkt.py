"""IpoptOptions.fast_kkt: IPOPT's fast KKT settings, on by default, same optimum."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import (
    BOUND_RELAX_FACTOR,
    FAST_KKT,
    RELAX_SHARE,
    IpoptOptions,
    bound_relaxation,
)


def test_fast_kkt_settings_reach_ipopt_and_records() -> None:
    """On by default (off for the IK path), overridable by extra, recorded only when off."""
    on = IpoptOptions().to_casadi(True)["ipopt"]
    assert all(on[k] == v for k, v in FAST_KKT.items())
    off = IpoptOptions(fast_kkt=False).to_casadi(True)["ipopt"]
    assert not set(FAST_KKT) & set(off)
    assert not set(FAST_KKT) & set(IpoptOptions.for_ikpath().to_casadi(True)["ipopt"])
    over = IpoptOptions(extra={"fast_step_computation": "no"}).to_casadi(True)["ipopt"]
    assert over["fast_step_computation"] == "no" and over["min_refinement_steps"] == 0
    spral = IpoptOptions(linear_solver="spral").to_casadi(True)["ipopt"]
    assert "fast_step_computation" in spral and not any(k.startswith("mumps_") for k in spral)
    assert "fast_kkt" not in IpoptOptions().to_dict()  # the dictionary earlier versions wrote
    assert IpoptOptions(fast_kkt=False).to_dict()["fast_kkt"] is False
    for options in (IpoptOptions(), IpoptOptions(fast_kkt=False), IpoptOptions.for_ikpath()):
        assert IpoptOptions(**options.to_dict()) == options
    with pytest.raises(ParameterError, match="fast_kkt must be True or False, got 'yes'"):
        IpoptOptions(fast_kkt="yes")  # type: ignore[arg-type]


def test_bound_relaxation_stays_within_a_share_of_the_tolerance() -> None:
    """IPOPT's default where its relaxation is small enough, else a factor that keeps it so."""
    assert (BOUND_RELAX_FACTOR, RELAX_SHARE) == (1e-8, 0.1)
    youbot = [np.array([-9.5, -2.0, 0.5]), np.array([9.5, np.inf, -np.inf])]
    assert bound_relaxation(youbot, 1e-6) == {}  # 9.5e-8 <= 1e-7: the study unchanged
    assert bound_relaxation([np.array([np.inf])], 1e-6) == {}  # |b| < 1 counts as 1
    ur5 = bound_relaxation([np.array([-150.0, 3.15]), np.array([150.0])], 1e-6)
    assert ur5["bound_relax_factor"] == pytest.approx(1e-7 / 150, rel=1e-15)
    assert ur5["bound_relax_factor"] * 150.0 <= RELAX_SHARE * 1e-6
    assert bound_relaxation(youbot, 1e-7)["bound_relax_factor"] == pytest.approx(1e-8 / 9.5)


@pytest.mark.parametrize("method", ["trapezoidal", "hermite_simpson", "radau"])
def test_fast_kkt_changes_the_steps_not_the_optimum(method: str) -> None:
    """Study-1 problem at 20 knots: the same local optimum with and without fast_kkt.

    fast_kkt includes MUMPS's AMD ordering (AMF for Radau): a different
    elimination order, so the Newton steps differ by rounding only.

    Both runs stop at IPOPT's tol = 1e-8 on the same KKT point: measured, their
    objectives differ by 4e-16 relative and their knots by 2e-13 rad (here the
    iterates coincide). The bounds (1e-8 relative, 1e-5 rad) allow another
    iteration path to the same point and stay far below the gap to another
    local optimum of this problem (distinct optima differ by > 1e-3 in f).
    """
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    problem = study1_problem(20)
    fast = TrajOptSolver(problem, method).solve(beta=0.5)
    plain = TrajOptSolver(problem, method, IpoptOptions(fast_kkt=False)).solve(beta=0.5)
    assert fast.success and plain.success, (fast.message, plain.message)
    assert fast.objective == pytest.approx(plain.objective, rel=1e-8)
    np.testing.assert_allclose(fast.variables["q"], plain.variables["q"], atol=1e-5)


@pytest.mark.parametrize(
    ("method", "order"), [("trapezoidal", 0), ("hermite_simpson", 0), ("radau", 2)]
)
def test_each_scheme_sets_its_mumps_ordering(
    method: str, order: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The IPOPT instances a solver builds (cold and warm) get the scheme's ordering.

    Only where FAST_KKT's ordering applies (fast_kkt on, MUMPS); ``extra`` wins.
    """
    import casadi as ca

    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    seen: list[dict[str, object]] = []
    build = ca.nlpsol

    def spy(name: str, plugin: str, nlp: object, opts: dict[str, object]) -> object:
        seen.append(dict(opts["ipopt"]))  # type: ignore[call-overload]
        return build(name, plugin, nlp, opts)

    monkeypatch.setattr(ca, "nlpsol", spy)
    problem = study1_problem(8)
    cases = [
        (IpoptOptions(), order),
        (IpoptOptions(extra={"mumps_pivot_order": 5}), 5),
        (IpoptOptions(fast_kkt=False), None),
        (IpoptOptions(linear_solver="spral"), None),
    ]
    for options, expected in cases:
        seen.clear()
        solver = TrajOptSolver(problem, method, options)
        first = solver.solve(beta=0.5)
        solver.solve(beta=0.5, guess=first, warm_start=True)
        assert len(seen) == 2, seen  # the cold and the warm instance
        for ipopt in seen:
            assert ipopt.get("mumps_pivot_order") == expected, (options, ipopt)
