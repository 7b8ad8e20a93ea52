"""Bounding balls: they contain the solid, their overshoot bounds the gap, fits are cached."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.collision import Box, Capsule, Cylinder, HalfSpace, Sphere
from youbot_opt.collision.spheres import (
    collision_cache_dir,
    fit_spheres,
    geometry_hull,
    hull_points,
)
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel


def _inside_union(points: np.ndarray, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    d = np.linalg.norm(points[:, None, :] - centers[None, :, :], axis=2) - radii[None, :]
    return d.min(axis=1)


def _surface_samples(
    rng: np.random.Generator, centers: np.ndarray, radii: np.ndarray, n: int
) -> np.ndarray:
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    k = rng.integers(len(radii), size=n)
    return centers[k] + radii[k, None] * u


def _distance_to_hull(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """coal's exact distance [m] of each point to the convex hull of ``vertices`` (the oracle)."""
    import coal

    from youbot_opt.collision.exact import convex_hull_solid

    solid = convex_hull_solid(vertices)
    point, request, out = coal.Sphere(1e-12), coal.DistanceRequest(), []
    for p in points:
        result = coal.DistanceResult()
        out.append(
            coal.distance(
                point, coal.Transform3s(np.eye(3), p), solid, coal.Transform3s(), request, result
            )
        )
    return np.array(out) + 1e-12


@pytest.mark.parametrize(
    "shape",
    [
        Box(size=(0.4, 0.1, 0.05)),
        Cylinder(radius=0.05, length=0.3),
        Capsule(radius=0.03, length=0.2),
        Sphere(radius=0.1),
    ],
)
def test_primitive_fit_contains_and_overshoot(shape, rng):
    """Every point of the solid's polytope is in a ball; no ball point lies beyond the overshoot."""
    hull = hull_points(shape)
    fit = fit_spheres(hull, cache=False)
    # the polytope's vertices are inside (so is each convex slab); 1e-12 m of round-off
    assert _inside_union(hull.points, fit.centers, fit.radii).max() <= 1e-12
    if hull.exact is None:
        samples = _surface_samples(rng, fit.centers, fit.radii, 5_000)
        # every sampled ball point lies within the overshoot of the solid (the slack included)
        assert _distance_to_hull(samples, hull.points).max() <= fit.overshoot


def test_ur5_link_fits_contain_their_meshes(ur5: RobotModel):
    """Each ur5 collision mesh's vertices lie in its balls; overshoots in (0, 8 cm)."""
    for geom in ur5.collision_model.geometryObjects:
        hull = geometry_hull(geom.geometry)
        fit = fit_spheres(hull)
        assert _inside_union(hull.points, fit.centers, fit.radii).max() <= 1e-12, geom.name
        assert 0.0 < fit.overshoot < 0.08, (geom.name, fit.overshoot)


def test_fits_are_cached(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """A fit is written to the cache folder once and read back equal."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    hull = hull_points(Box(size=(0.3, 0.2, 0.1)))
    first = fit_spheres(hull)
    files = list((tmp_path / "collision").glob("spheres-*.json"))
    assert collision_cache_dir() == tmp_path / "collision" and len(files) == 1
    second = fit_spheres(hull)
    np.testing.assert_array_equal(first.centers, second.centers)
    assert first.overshoot == second.overshoot
    files[0].write_text("not json")  # a broken cache entry is fitted again
    assert fit_spheres(hull).overshoot == first.overshoot
    assert os.path.getsize(files[0]) > 10


def test_halfspace_has_no_balls():
    """A half-space is unbounded: fitting it is refused."""
    with pytest.raises(ParameterError, match="unbounded"):
        hull_points(HalfSpace())


def test_wide_box_is_cut_across(rng):
    """A flat, wide box (the youBot platform's shape) is cut along two axes, not into slabs.

    Slabs along its long side give balls as wide as the box (overshoot about
    16 cm on the platform); cells across both long sides keep it under 6 cm,
    with every corner inside and every sampled ball point within the overshoot.
    """
    hull = hull_points(Box(size=(0.6, 0.4, 0.1)))
    fit = fit_spheres(hull, cache=False)
    assert len(fit.radii) <= 16
    assert fit.overshoot < 0.06
    spread = np.ptp(fit.centers, axis=0)
    assert spread[0] > 0.1 and spread[1] > 0.1  # centres spread over both long sides
    assert _inside_union(hull.points, fit.centers, fit.radii).max() <= 1e-12
    samples = _surface_samples(rng, fit.centers, fit.radii, 5_000)
    assert _distance_to_hull(samples, hull.points).max() <= fit.overshoot


def test_count_cap(rng):
    """The count cap bounds the ball count; on a wide plate a cap of 16 fits tighter than 4."""
    hull = hull_points(Box(size=(0.5, 0.3, 0.08)))
    small = fit_spheres(hull, max_spheres=4, target_overshoot=0.0, cache=False)
    large = fit_spheres(hull, max_spheres=16, target_overshoot=0.0, cache=False)
    assert len(small.radii) <= 4 and len(large.radii) <= 16
    assert large.overshoot < small.overshoot


def test_study_youbot_self_collision_allows_a_realistic_margin():
    """At the study's start and goal the youBot's self pairs read >= 5 cm apart in the ball model.

    The slab fit read 6 mm at the start and -37 mm at the goal (the platform's
    balls overshot its box by 16 cm), so self-collision was infeasible at any
    useful margin.
    """
    from youbot_opt.collision import Scene
    from youbot_opt.collision.exact import exact_checker
    from youbot_opt.collision.model import build_collision_model, joint_placements
    from youbot_opt.reproduction.study1 import STUDY_Q_GOAL, STUDY_Q_START
    from youbot_opt.robot.load import load_model

    robot = load_model("youbot")
    cm = build_collision_model(robot, Scene(()))
    assert cm.self_pairs
    function, checker = cm.distance_function(), exact_checker(cm, robot)
    for q in (np.array(STUDY_Q_START), np.array(STUDY_Q_GOAL)):
        model = np.asarray(function(*joint_placements(robot, q))).ravel()
        exact = checker.distances(robot, q)
        assert model.min() >= 0.05, dict(zip(cm.pair_names, model, strict=True))
        assert np.all(model <= exact + 1e-9)  # still conservative
