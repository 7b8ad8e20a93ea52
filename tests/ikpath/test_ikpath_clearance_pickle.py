"""An IK problem with a clearance sent to another process (#28): small, and solved the same.

The ur5 with a box and self-collision (the SRDF's 16 pairs): its pickle held coal's
text archive of the 7 collision meshes (9.9 MB); the meshes now travel as arrays
(:mod:`youbot_opt.collision.packed`) and a spawned worker rebuilds the same model,
the same rows and so the same solve.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import pickle
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import coal
import numpy as np
import pytest

from youbot_opt.collision import Box, Obstacle, Scene
from youbot_opt.collision.clearance import Clearance
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.solve import solve
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.load import load_model

TARGETS = (Target(position=(0.4, 0.2, 0.3)), Target(position=(0.3, -0.3, 0.4)))
#: Pinocchio's text archive of one geometry object without its mesh: 1.3 KB measured.
OBJECT_BYTES = 2_000
#: The clearance (a box scene, margin, pairs) and the pickle's framing: 0.5 KB measured.
SPEC_BYTES = 4_000


@pytest.fixture(scope="module")
def problem(fit_cache: Path) -> Iterator[CyclicIKProblem]:
    """ur5, two targets, a box under the forearm's sweep, self-collision (SRDF pairs)."""
    box = Obstacle(name="box", shape=Box(size=(0.1, 0.1, 0.1)), xyz=(0.3, -0.05, -0.15))
    clearance = Clearance(scene=Scene((box,)), margin=0.01, self_collision=True)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("YOUBOT_OPT_CACHE", str(fit_cache))  # a spawned worker inherits it
        yield CyclicIKProblem(robot=load_model("ur5"), targets=TARGETS, clearance=clearance)


def test_the_pickle_carries_the_meshes_as_arrays(problem: CyclicIKProblem) -> None:
    """Bounded by the problem without clearance plus the meshes' arrays (0.16 MB, was 9.9 MB).

    Unpickled in this process, the problem holds this process's collision model and rows.
    """
    geometry = problem.robot_model.collision_model
    meshes = [o.geometry for o in geometry.geometryObjects]
    arrays = sum(
        24 * g.num_vertices + 12 * g.num_tris for g in meshes if isinstance(g, coal.BVHModelBase)
    )
    bare = len(pickle.dumps(dataclasses.replace(problem, clearance=None)))
    data = pickle.dumps(problem)
    assert len(data) <= bare + arrays + OBJECT_BYTES * geometry.ngeoms + SPEC_BYTES
    here = pickle.loads(data)
    assert here.robot_model.collision_model is geometry
    assert here.clearance_rows is problem.clearance_rows


def test_a_spawned_worker_solves_the_same_path(problem: CyclicIKProblem) -> None:
    """The AL in a spawned process (the geometry and rows rebuilt there): the same E and path.

    Same numbers in, same code: equal to the last bit. With the SRDF's pairs the
    margin cannot be kept (the balls of wrist_1 and ee_link overlap by 0.023 m on
    every step), so the run ends infeasible after 8 outer iterations: a long run
    through the rows, which the worker repeats exactly.
    """
    start = solve(dataclasses.replace(problem, clearance=None), method="al").configurations
    here = solve(problem, method="al", x0=start)
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        there = pool.submit(solve, problem, method="al", x0=start).result()
    assert there.status is here.status
    assert there.objective == here.objective
    np.testing.assert_array_equal(there.configurations, here.configurations)
    # sent back, the result's problem holds this process's geometry and rows again
    assert there.problem.robot_model.collision_model is problem.robot_model.collision_model
    assert there.problem.clearance_rows is problem.clearance_rows
