"""BFGS with strong Wolfe line search: Wolfe conditions, convergence, bounds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize, rosen, rosen_der

from youbot_opt.ikpath.methods.bfgs import minimize_bfgs, strong_wolfe_line_search


def _rosen(x):
    return float(rosen(x)), rosen_der(x)


def test_line_search_meets_strong_wolfe(rng):
    """Accepted steps satisfy both strong Wolfe inequalities (checked by re-evaluation)."""
    c1, c2 = 1e-4, 0.9
    for _ in range(20):
        x = rng.uniform(-2, 2, 4)
        f0, g0 = _rosen(x)
        p = -g0 / np.linalg.norm(g0)
        ls = strong_wolfe_line_search(_rosen, x, f0, g0, p, alpha0=1.0, c1=c1, c2=c2, f_noise=0.0)
        assert ls.success
        f, g = _rosen(x + ls.alpha * p)
        assert f <= f0 + c1 * ls.alpha * (g0 @ p)
        assert abs(g @ p) <= c2 * abs(g0 @ p)


def test_bfgs_solves_rosenbrock():
    """BFGS reaches the Rosenbrock minimum (1, ..., 1) in 10-D (1e-7, as gtol 1e-10 allows)."""
    res = minimize_bfgs(_rosen, np.zeros(10), gtol=1e-10, max_iterations=500)
    assert res.converged
    np.testing.assert_allclose(res.x, np.ones(10), atol=1e-7)


def test_bfgs_gradient_tolerance_below_rounding_of_f():
    """The approximate-Wolfe safeguard lets the gradient reach 1e-12 on an ill-scaled quadratic."""
    scales = np.logspace(0, 4, 6)
    target = np.linspace(-1, 1, 6)

    def fun(x):
        d = x - target
        return 1e3 + 0.5 * float(np.sum(scales * d * d)), scales * d

    res = minimize_bfgs(fun, np.zeros(6), gtol=1e-12, max_iterations=500)
    assert res.converged
    # gradient <= 1e-12 with curvature >= 1 means |x - x*| <= 1e-12
    np.testing.assert_allclose(res.x, target, atol=1e-11)


def test_projected_bfgs_matches_analytic_box_quadratic(rng):
    """On a separable quadratic the bounded solution is the clipped minimiser (1e-10)."""
    centre = rng.uniform(-3, 3, 8)
    curv = rng.uniform(0.5, 5.0, 8)
    lo, hi = np.full(8, -1.0), np.full(8, 1.5)

    def fun(x):
        d = x - centre
        return 0.5 * float(np.sum(curv * d * d)), curv * d

    res = minimize_bfgs(fun, np.zeros(8), lower=lo, upper=hi, gtol=1e-11)
    assert res.converged
    np.testing.assert_allclose(res.x, np.clip(centre, lo, hi), atol=1e-10)
    assert np.all(res.x >= lo) and np.all(res.x <= hi)


def test_projected_bfgs_matches_lbfgsb_on_bounded_rosenbrock():
    """Bounded Rosenbrock: same minimiser as SciPy's L-BFGS-B, an independent code (1e-6)."""
    lo, hi = np.full(6, -0.5), np.full(6, 0.7)
    ours = minimize_bfgs(_rosen, np.zeros(6), lower=lo, upper=hi, gtol=1e-10)
    ref = minimize(
        rosen,
        np.zeros(6),
        jac=rosen_der,
        method="L-BFGS-B",
        bounds=list(zip(lo, hi, strict=True)),
        options={"gtol": 1e-12, "ftol": 0.0, "maxiter": 5000},
    )
    assert ours.converged
    # both stop at projected gradient ~1e-10; the reduced Hessian is well conditioned here
    np.testing.assert_allclose(ours.x, ref.x, atol=1e-6)
    assert ours.f == pytest.approx(ref.fun, abs=1e-10)


def test_bfgs_deadline_stops_before_the_next_iteration():
    """A passed deadline returns the start untouched; a far one changes nothing."""
    x0 = np.zeros(4)
    stopped = minimize_bfgs(_rosen, x0, gtol=1e-10, deadline=0.0)  # perf_counter() > 0 always
    assert stopped.iterations == 0 and not stopped.converged
    assert stopped.message == "time limit reached"
    np.testing.assert_array_equal(stopped.x, x0)
    free = minimize_bfgs(_rosen, x0, gtol=1e-10)
    far = minimize_bfgs(_rosen, x0, gtol=1e-10, deadline=float("inf"))
    assert far.iterations == free.iterations and far.converged
    np.testing.assert_array_equal(far.x, free.x)
