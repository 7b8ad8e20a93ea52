"""Property tests of the trajectory API: a status that matches an independent check, or an error.

Hypothesis draws valid and invalid inputs (boundary states inside and outside
the bounds, ``beta`` in and out of [0, 1], 0..40 knots, ``bound_scale <= 0``,
wrong shapes, NaN/inf, tiny iteration and CPU-time caps). Every call must
either raise a documented :class:`~youbot_opt.exceptions.YoubotOptError` or
return a result whose status is the one :func:`~youbot_opt.result.check_result`
(accelerations by ``pin.aba``, not the NLP's CasADi dynamics) gives it, with
bounds re-checked by :func:`~youbot_opt.verify.check_bounds`. Runs are
derandomized and database-free, so CI sees the same examples every time.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from youbot_opt.exceptions import ParameterError, SolveFailed
from youbot_opt.model import load_model
from youbot_opt.options import IpoptOptions
from youbot_opt.problem import BoundaryState, TrajOptProblem
from youbot_opt.result import SolveStatus, TrajOptResult, check_result
from youbot_opt.solve import TrajOptSolver
from youbot_opt.verify import check_bounds

PROPERTY = settings(
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

# Solver builds cost 0.1-1.5 s, so the solvers are cached per (knots, method, options).
_SOLVERS: dict[tuple[Any, ...], TrajOptSolver] = {}

# Guard against hangs only (no timing claim): a capped solve must stop within
# 10x its CPU-time cap plus 2 s for the checks and the process's other work.
HANG_FACTOR, HANG_MARGIN = 10.0, 2.0  # [-], [s]


@pytest.fixture(scope="module")
def youbot():
    """The planar youBot with the study code's joint damping."""
    return load_model("youbot", damping=0.1)


def _solver(problem: TrajOptProblem, method: str, options: IpoptOptions) -> TrajOptSolver:
    key = (problem.n_knots, method, options.max_iter, options.max_cpu_time, problem.duration)
    key += (problem.start.q.tobytes(), problem.goal.q.tobytes())
    if key not in _SOLVERS:
        _SOLVERS[key] = TrajOptSolver(problem, method, options)
    return _SOLVERS[key]


_SPECIAL = st.sampled_from([math.nan, math.inf, -math.inf])
_FRACTIONS = st.lists(st.floats(-0.9, 0.9), min_size=3, max_size=3)


def _inside(robot: Any, fractions: list[float]) -> list[float]:
    """q at ``fractions`` (in [-1, 1]) of the half range about the middle of the limits."""
    lo, hi = np.asarray(robot.q_lower), np.asarray(robot.q_upper)
    return list(0.5 * (lo + hi) + 0.5 * (hi - lo) * np.asarray(fractions))


def _call(robot: Any, n_knots: Any, method: str, inputs: dict[str, Any]) -> TrajOptResult:
    """Build options, problem and (cached) solver, then solve: the whole public path."""
    opts = IpoptOptions(max_iter=inputs["max_iter"], max_cpu_time=inputs["max_cpu_time"])
    problem = TrajOptProblem(
        robot=robot,
        start=BoundaryState(q=inputs["start"]),
        goal=BoundaryState(q=inputs["goal"]),
        n_knots=n_knots,
        duration=inputs["duration"],
    )
    solver = _solver(problem, method, opts)
    return solver.solve(beta=inputs["beta"], bound_scale=inputs["bound_scale"])


@settings(PROPERTY, max_examples=25)
@given(
    n_knots=st.integers(2, 40),
    method=st.sampled_from(["trapezoidal", "hermite_simpson"]),
    start=_FRACTIONS,
    goal=_FRACTIONS,
    beta=st.floats(0.0, 1.0),
    bound_scale=st.floats(0.5, 1.2),
    max_iter=st.sampled_from([0, 1, 5, 300, 300]),
    max_cpu_time=st.sampled_from([None, 1e-3, 0.5, 1.0]),
    duration=st.one_of(st.none(), st.floats(0.5, 3.0)),
)
def test_valid_inputs_status_matches_independent_check(
    youbot, n_knots, method, start, goal, beta, bound_scale, max_iter, max_cpu_time, duration
) -> None:
    """Valid inputs never raise; the returned status is the one check_result gives."""
    # Boundary states inside the scaled bounds (position bounds scale about zero).
    shrink = min(bound_scale, 1.0)
    inputs = dict(
        start=shrink * np.array(_inside(youbot, start)),
        goal=shrink * np.array(_inside(youbot, goal)),
        beta=beta, bound_scale=bound_scale, max_iter=max_iter, max_cpu_time=max_cpu_time,
        duration=duration,
    )  # fmt: skip
    tic = time.process_time()
    result = _call(youbot, n_knots, method, inputs)
    event(f"returned {result.status.value}")
    _assert_honest(result)
    assert result.iterations <= max_iter
    if max_cpu_time is not None:  # hang guard only, see HANG_FACTOR
        limit = HANG_FACTOR * max_cpu_time + HANG_MARGIN
        assert result.cpu_time <= limit
        assert time.process_time() - tic <= limit + 2.0  # + a possible solver build


_VALID = dict(
    start=[-0.5, -0.5, -1.0], goal=[0.5, 0.5, 1.0], beta=0.5, bound_scale=1.0,
    max_iter=3, max_cpu_time=None, duration=None,
)  # fmt: skip
_INVALID: dict[str, st.SearchStrategy[Any]] = {
    "n_knots": st.sampled_from([0, 1, -3, 2.5, True, "50", None]),
    "beta": st.one_of(
        st.floats(1.0, 10.0, exclude_min=True), st.floats(-10.0, 0.0, exclude_max=True), _SPECIAL
    ),
    "bound_scale": st.one_of(st.floats(-10.0, 0.0), _SPECIAL, st.just(None)),
    "start": st.one_of(
        st.tuples(_SPECIAL, st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)).map(list),
        st.lists(st.floats(-0.5, 0.5), max_size=6).filter(lambda v: len(v) != 3),
        st.tuples(st.floats(3.5, 1e6), st.just(0.0), st.just(0.0)).map(list),
        st.just([[0.0, 0.0, 0.0]]),
    ),
    "goal": st.one_of(
        st.tuples(st.floats(-0.5, 0.5), _SPECIAL, st.floats(-0.5, 0.5)).map(list),
        st.tuples(st.just(0.0), st.just(0.0), st.floats(-1e6, -5.0)).map(list),
        st.just("up"),
    ),
    "max_iter": st.sampled_from([-1, 2.5, None, True]),
    "max_cpu_time": st.one_of(st.floats(-10.0, 0.0), _SPECIAL),
    "duration": st.one_of(st.floats(-10.0, 0.0), _SPECIAL),
}


@settings(PROPERTY, max_examples=60)
@given(
    field=st.sampled_from(sorted(_INVALID)),
    data=st.data(),
    method=st.sampled_from(["trapezoidal", "hermite_simpson"]),
)
def test_one_invalid_input_raises_parameter_error(youbot, field, data, method) -> None:
    """Exactly one invalid input (NaN/inf, sign, range, shape, type) raises ParameterError."""
    value = data.draw(_INVALID[field], label=field)
    inputs = dict(_VALID)
    n_knots: Any = 4
    if field == "n_knots":
        n_knots = value
    else:
        inputs[field] = value
    with pytest.raises(ParameterError) as info:
        _call(youbot, n_knots, method, inputs)
    assert str(info.value)


def _assert_honest(result: TrajOptResult) -> None:
    """The result's status is the independent check's; failures explain themselves."""
    check = check_result(result)
    assert result.status is check.status, (result.status, check)
    assert result.success == check.passed
    if result.success:
        # Independent bound check at the knots, on the Trajectory (not the NLP vector):
        # IPOPT relaxes bounds by 1e-8 relative, far inside feasibility_tol = 1e-6.
        assert result.trajectory is not None
        for c in check_bounds(result.trajectory, result.bounds()):
            if c.where == "knots":
                assert c.excess <= result.feasibility_tol, c
        assert check.defect <= result.feasibility_tol
        assert math.isfinite(result.objective) and result.duration > 0
    else:
        assert result.message
        with pytest.raises(SolveFailed) as info:
            result.raise_for_status()
        assert info.value.result is result
        # The best iterate is returned with every block of the right shape.
        assert result.variables["q"].shape == (result.problem.n_knots, result.problem.nv)


# --------------------------------------------------------------------- corrupted results
@pytest.fixture(scope="module")
def solved(youbot) -> dict[str, TrajOptResult]:
    """A converged 12-knot study-1 solve per transcription."""
    out = {}
    for method in ("trapezoidal", "hermite_simpson"):
        problem = TrajOptProblem(
            robot=youbot,
            start=BoundaryState(q=[-math.pi / 6, -math.pi / 6, -math.pi / 3]),
            goal=BoundaryState(q=[math.pi / 6, math.pi / 6, math.pi / 3]),
            n_knots=12,
        )
        out[method] = TrajOptSolver(problem, method).solve(beta=0.5).raise_for_status()
    return out


@settings(PROPERTY, max_examples=80)
@given(
    method=st.sampled_from(["trapezoidal", "hermite_simpson"]),
    block=st.sampled_from(["q", "v", "tau", "dt", "q_mid", "v_mid", "tau_mid"]),
    where=st.floats(0.0, 1.0, exclude_max=True),
    joint=st.integers(0, 2),
    corruption=st.one_of(_SPECIAL, st.floats(1e-4, 10.0), st.floats(-10.0, -1e-4)),
)
def test_corrupted_solution_is_never_a_success(
    solved, method, block, where, joint, corruption
) -> None:
    """NaN/inf or a perturbation > 1e-4 in any variable turns a success into a failure."""
    good = solved[method]
    if block not in good.variables:
        block = "q"
    arr = np.array(good.variables[block])
    k = int(where * arr.shape[0])
    j = min(joint, arr.shape[1] - 1)
    arr[k, j] = corruption if not math.isfinite(corruption) else arr[k, j] + corruption
    bad = dataclasses.replace(good, variables={**good.variables, block: arr})
    check = check_result(bad)
    assert not check.passed and not bad.success
    assert bad.status is check.status
    expected = SolveStatus.NON_FINITE if not math.isfinite(corruption) else None
    if expected is not None:
        assert bad.status is expected
    with pytest.raises(SolveFailed, match=bad.status.value):
        bad.raise_for_status()
