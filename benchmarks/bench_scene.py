"""Clearance side by side with Drake (issue 28, item 8): the same scene, robot and configurations.

Run ``python benchmarks/bench_scene.py [--quick] [--all [--robots ur5,panda]]
[--scene FILE] [--robot ur5|panda] [--pairs N] [--first-pair K] [--no-refine]
[--refine-pairs N] [--no-dense] [--no-dircol] [--dircol-pairs N]
[--dircol-cost simpson|trapezoid] [--no-solve] [--json]``. Drake comes with the ``bench`` extra
(``pip install -e ".[bench]"``); without it the script prints that and exits
with 2, measuring nothing.

* **The scene** is a scene file of our format (``--scene``; by default the cell
  of notebook 08: a table, a shelf panel and a box held by ``tool0``) read by
  :func:`youbot_opt.collision.load_scene`. ``--all`` runs the four cells
  {ur5, panda} x {``pick_place_pillar``, ``shelf_reach``} of
  ``benchmarks/scenes`` (written by ``benchmarks/scenes/make_scenes.py``:
  one scene file per robot, placed from its reach, and 20 seeded start/goal
  pairs in ``<robot>_<scene>_pairs.json`` whose straight joint-space line
  collides), one after the other, then a summary table. A scene file with a
  ``<stem>_pairs.json`` beside it is solved on those pairs. Drake gets the same primitives as
  Drake shapes (boxes as ``Box``, ...), world-fixed ones on the world body and
  carried ones on the carrying link's body at the same pose.
* **The robot** (``--robot``; ``panda`` with its finger joint locked at 0,
  as ``--lock panda_finger_joint1=0`` does in the CLI, its mimic following) is
  parsed by Drake's ``Parser`` from the same URDF text (its visual and
  collision elements taken out, each locked joint made ``fixed`` at its locked
  position by :func:`weld_locked`, the root link welded to the world), and
  each collision geometry of our model is registered on the same body at the
  same pose: a mesh as a ``Convex``
  read from an ``.obj`` file holding the convex hull of the mesh's vertices
  (:func:`hull_obj_text`), the solid coal measures too; a primitive as itself.
  Collision filters leave exactly our robot-vs-scene pairs (no self pairs, no
  obstacle-vs-obstacle pairs, a held box not against the links holding it).
* **Configurations**: the knots of our solved plan (Hermite-Simpson, a margin
  of 1 cm from the scene) and ``--samples`` samples between each two knots.
  At each one, every pair's distance by coal
  (:class:`youbot_opt.collision.ExactChecker`, the certificate's checker) and by
  Drake's ``QueryObject.ComputeSignedDistancePairwiseClosestPoints``; printed:
  max |ours - Drake| [m], the closest pair each reports, and the time per
  configuration of each (forward kinematics included; medians of ``--repeats``
  passes, in the same run).
* **Solves** on ``--pairs`` start/goal pairs (the scene's pairs file, else
  notebook 08's pick and place, then seeded perturbations of both, each end
  within the limits and at least the margin from the scene by coal): ours
  (``TrajOptSolver.solve`` on one
  built solver, full dynamics, torque limits and the clearance rows; also the
  whole of ``refine()``, and the same solver without the scene: what the
  scene costs) against Drake's ``KinematicTrajectoryOptimization`` with
  ``MinimumDistanceLowerBoundConstraint`` at as many path samples as we have
  constrained points (SNOPT and IPOPT), and at four times as many (SNOPT).
  That problem has **no dynamics** (a B-spline path with duration,
  velocity and position bounds, minimum time plus path length): it is a
  kinematic reference, not the same problem. Drake on **our dynamic problem**
  (:class:`DrakeDircol`, unless ``--no-dircol``; ``--dircol-pairs N``: the
  first N pairs only): ``DirectCollocation`` on a plant from the same URDF
  text, every joint actuated, gravity, our bounds, knots, free equal steps,
  ``beta T + (1 - beta) W`` and the ends at rest, with
  ``MinimumDistanceLowerBoundConstraint`` (the margin) at every knot, from
  our straight-line guess (SNOPT and IPOPT; the differences from ours are in
  the class's docstring and docs/scene.md). Every plan is then judged by one
  exact checker, coal's certificate of docs/scene.md (samples and the
  point-speed bound): success is the solver's success and the margin, less
  1 mm, certified over the whole plan.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

DRAKE_HINT = 'pip install -e ".[bench]"'
ROBOT = "ur5"
Q_PICK = np.array([-0.6, -1.0, 1.6, -2.1, -1.57, 0.0])  # [rad] notebook 08's pick pose
Q_PLACE = np.array([0.6, -1.0, 1.6, -2.1, -1.57, 0.0])  # [rad] and place pose
MARGIN = 0.01  # [m]
SCENES_DIR = Path(__file__).resolve().parent / "scenes"
SCENES = ("pick_place_pillar", "shelf_reach")
BETA = 0.5
#: The cell of notebook 08 (a table, a shelf panel on it, a box held by the tool).
CELL = {
    "schema": "youbot_opt.scene",
    "schema_version": 1,
    "obstacles": [
        {"name": "table", "shape": "box", "size": [0.5, 1.4, 0.04], "xyz": [0.55, 0.0, -0.02]},
        {"name": "shelf", "shape": "box", "size": [0.3, 0.03, 0.3], "xyz": [0.6, 0.08, 0.15]},
        {
            "name": "held box",
            "shape": "box",
            "size": [0.06, 0.06, 0.06],
            "xyz": [0, 0, 0.04],
            "frame": "tool0",
        },
    ],
}


# -- pure helpers (no Drake) ------------------------------------------------------------


def hull_obj_text(points: np.ndarray) -> str:
    """Return Wavefront OBJ text of the convex hull of ``points`` [m] (outward triangles).

    Drake's ``Convex`` reads an ``.obj``; the solid is the hull of its
    vertices, as coal's convex hull of the same mesh (``collision.exact``).
    """
    from scipy.spatial import ConvexHull

    pts = np.asarray(points, dtype=float)
    hull = ConvexHull(pts)
    used = np.unique(hull.simplices)
    index = {int(v): i + 1 for i, v in enumerate(used)}
    centre = pts[used].mean(axis=0)
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in pts[used]]
    for tri in hull.simplices:
        a, b, c = (pts[i] for i in tri)
        if np.dot(np.cross(b - a, c - a), a - centre) < 0:  # orient outwards
            tri = tri[[0, 2, 1]]
        lines.append("f " + " ".join(str(index[int(i)]) for i in tri))
    return "\n".join(lines) + "\n"


def strip_geometry(urdf: str) -> str:
    """Return URDF text without ``<visual>`` and ``<collision>`` elements (Drake gets ours)."""
    return re.sub(r"<(visual|collision)\b.*?</\1>", "", urdf, flags=re.DOTALL)


def weld_locked(urdf: str, locked: tuple[tuple[str, float], ...]) -> str:
    """Return URDF text with each joint of ``locked`` made ``fixed`` at its locked position.

    ``locked`` is :attr:`RobotModel.locked_joints` (mimic joints included, at
    their values): the joint's origin takes the motion (a prismatic joint's
    translation along its axis, a revolute joint's rotation about it) and its
    ``<mimic>`` goes, so Drake welds the same bodies where our model has them.
    """
    import xml.etree.ElementTree as ET

    import pinocchio as pin

    values = dict(locked)
    root = ET.fromstring(urdf)
    for joint in root.iter("joint"):
        name = joint.get("name", "")
        if name not in values:
            continue
        kind = joint.get("type")
        axis_el = joint.find("axis")
        axis = np.array([float(v) for v in (axis_el.get("xyz", "1 0 0") if axis_el is not None
                                          else "1 0 0").split()])  # fmt: skip
        origin = joint.find("origin")
        if origin is None:
            origin = ET.SubElement(joint, "origin")
        xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
        rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
        rot = pin.rpy.rpyToMatrix(rpy)
        value = values[name]
        if kind == "prismatic":
            xyz = xyz + rot @ (value * axis)
        elif kind in ("revolute", "continuous"):
            rot = rot @ pin.exp3(value * axis / np.linalg.norm(axis))
        else:
            raise NotImplementedError(f"{name}: cannot weld a {kind} joint")
        origin.set("xyz", " ".join(f"{v:.12g}" for v in xyz))
        origin.set("rpy", " ".join(f"{v:.12g}" for v in pin.rpy.matrixToRpy(rot)))
        joint.set("type", "fixed")
        for child in list(joint):
            if child.tag in ("mimic", "axis", "limit", "dynamics", "safety_controller"):
                joint.remove(child)
    return ET.tostring(root, encoding="unicode")


def _root_link(urdf: str) -> str:
    """The URDF's root link: the one no joint has as its child."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(urdf)
    children = {c.get("link") for c in root.iter("child")}
    (name,) = [n for link in root.iter("link") if (n := link.get("name", "")) not in children]
    return name


def _timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """``fn()``, its wall time and its CPU time in [s]."""
    wall, cpu = time.perf_counter(), time.process_time()
    value = fn()
    return value, time.perf_counter() - wall, time.process_time() - cpu


# -- Drake's side -------------------------------------------------------------------------


def _rigid(rotation: np.ndarray, translation: np.ndarray) -> Any:
    from pydrake.math import RigidTransform, RotationMatrix

    return RigidTransform(RotationMatrix(np.asarray(rotation)), np.asarray(translation))


class DrakeScene:
    """Our robot and scene in a Drake diagram (``MultibodyPlant`` + ``SceneGraph``).

    Attributes set: ``plant``, ``scene_graph``, ``diagram``, ``context``,
    ``plant_context``, ``urdf`` (the text parsed), ``names`` (GeometryId -> our
    geometry or obstacle name), ``order`` (our q index -> Drake's), ``pairs``
    (our scene pairs as name pairs).
    """

    def __init__(self, robot: Any, checker: Any, folder: Path) -> None:
        import coal
        import pinocchio as pin
        from pydrake.geometry import (
            Box,
            Capsule,
            CollisionFilterDeclaration,
            Convex,
            Cylinder,
            GeometrySet,
            HalfSpace,
            ProximityProperties,
            Sphere,
        )
        from pydrake.multibody.parsing import Parser
        from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
        from pydrake.systems.framework import DiagramBuilder

        from youbot_opt.collision import shapes

        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.0)
        urdf = Path(robot.urdf_path).read_text(encoding="utf-8")
        urdf = strip_geometry(weld_locked(urdf, robot.locked_joints))
        (instance,) = Parser(plant).AddModelsFromString(urdf, "urdf")
        root = _root_link(urdf)
        if root != "world":  # our models have a fixed base: weld the root link at the origin
            plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(root, instance))
        model = robot.model
        names: dict[Any, str] = {}

        def register(body: Any, pose: Any, shape: Any, name: str) -> None:
            gid = plant.RegisterCollisionGeometry(body, pose, shape, name, ProximityProperties())
            names[gid] = name

        for geom in robot.collision_model.geometryObjects:
            frame = model.frames[geom.parentFrame]
            body = plant.GetBodyByName(frame.name, instance)
            # geometry placement is in the parent joint's frame; Drake wants the body's
            x = frame.placement.inverse() * pin.SE3(geom.placement)
            g = geom.geometry
            if isinstance(g, coal.BVHModelBase):
                path = folder / f"{geom.name}.obj"
                path.write_text(hull_obj_text(np.asarray(g.vertices())), encoding="utf-8")
                shape: Any = Convex(str(path))
            elif isinstance(g, coal.Box):
                shape = Box(*(2 * np.asarray(g.halfSide)))
            elif isinstance(g, coal.Sphere):
                shape = Sphere(g.radius)
            elif isinstance(g, coal.Cylinder):
                shape = Cylinder(g.radius, 2 * g.halfLength)
            elif isinstance(g, coal.Capsule):
                shape = Capsule(g.radius, 2 * g.halfLength)
            else:
                raise NotImplementedError(f"{geom.name}: {type(g).__name__} has no Drake shape")
            register(body, _rigid(x.rotation, x.translation), shape, geom.name)
        for placed in checker.model.obstacles:
            o = placed.obstacle
            s = o.shape
            if isinstance(s, shapes.Box):
                shape = Box(*s.size)
            elif isinstance(s, shapes.Sphere):
                shape = Sphere(s.radius)
            elif isinstance(s, shapes.Cylinder):
                shape = Cylinder(s.radius, s.length)
            elif isinstance(s, shapes.Capsule):
                shape = Capsule(s.radius, s.length)
            elif isinstance(s, shapes.HalfSpace):
                shape = HalfSpace()
            else:  # a mesh: its convex hull, as coal's
                from youbot_opt.collision.spheres import hull_points

                path = folder / f"obstacle_{len(names)}.obj"
                path.write_text(hull_obj_text(hull_points(s).points), encoding="utf-8")
                shape = Convex(str(path))
            if o.frame is None:
                body = plant.world_body()
                pose = _rigid(o.rotation, o.translation)
            else:  # URDF fixed joints stay bodies in Drake: the frame's body, at its pose
                frame = plant.GetFrameByName(o.frame, instance)
                body = frame.body()
                pose = frame.GetFixedPoseInBodyFrame().multiply(_rigid(o.rotation, o.translation))
            register(body, pose, shape, o.name)
        plant.Finalize()
        # leave exactly our robot-vs-scene pairs
        ours = set(checker.model.pair_names[len(checker.model.self_pairs) :])
        ids = list(names)
        manager = scene_graph.collision_filter_manager()
        for i, a in enumerate(ids):
            for b in ids[i + 1 :]:
                pair = (names[a], names[b])
                if pair in ours or pair[::-1] in ours:
                    continue
                manager.Apply(
                    CollisionFilterDeclaration().ExcludeBetween(GeometrySet(a), GeometrySet(b))
                )
        self.diagram = builder.Build()
        self.urdf = urdf  # the text Drake parsed (locked joints welded, no geometry)
        self.context = self.diagram.CreateDefaultContext()
        self.plant, self.scene_graph = plant, scene_graph
        self.plant_context = plant.GetMyMutableContextFromRoot(self.context)
        self.sg_context = scene_graph.GetMyContextFromRoot(self.context)
        self.names = names
        self.pairs = tuple(checker.model.pair_names[len(checker.model.self_pairs) :])
        self.pair_index = {p: i for i, p in enumerate(self.pairs)}
        drake_names = [
            plant.get_joint(j).name()
            for j in plant.GetJointIndices(instance)
            if plant.get_joint(j).num_positions() == 1
        ]
        starts = {
            plant.get_joint(j).name(): plant.get_joint(j).position_start()
            for j in plant.GetJointIndices(instance)
        }
        ours_names = [model.names[j] for j in range(1, model.njoints)]
        if sorted(drake_names) != sorted(ours_names):
            raise ValueError(f"joints differ: Drake {drake_names}, ours {ours_names}")
        self.order = np.array([starts[n] for n in ours_names])
        self.nq = plant.num_positions()

    def to_drake(self, q: np.ndarray) -> np.ndarray:
        """Our configuration in Drake's joint order."""
        out = np.zeros(self.nq)
        out[self.order] = q
        return out

    def from_drake(self, q: np.ndarray) -> np.ndarray:
        """Drake's configuration in our joint order."""
        return np.asarray(q)[self.order]

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Drake's signed distance [m] of each of our scene pairs at our ``q``, in our order."""
        self.plant.SetPositions(self.plant_context, self.to_drake(q))
        query = self.scene_graph.get_query_output_port().Eval(self.sg_context)
        out = np.full(len(self.pairs), np.nan)
        for r in query.ComputeSignedDistancePairwiseClosestPoints():
            a, b = self.names[r.id_A], self.names[r.id_B]
            k = self.pair_index.get((a, b), self.pair_index.get((b, a)))
            if k is None:
                raise AssertionError(f"Drake reports a pair we do not check: {a} - {b}")
            out[k] = r.distance
        return out

    def link_pose_error(self, robot: Any, frames: list[str], qs: np.ndarray) -> float:
        """Largest |position difference| [m] of ``frames`` between Drake and Pinocchio."""
        import pinocchio as pin

        data = robot.create_data()
        worst = 0.0
        for q in qs:
            pin.framesForwardKinematics(robot.model, data, q)
            self.plant.SetPositions(self.plant_context, self.to_drake(q))
            for name in frames:
                ours = data.oMf[robot.frame_id(name)].translation
                theirs = self.plant.GetFrameByName(name).CalcPoseInWorld(self.plant_context)
                worst = max(worst, float(np.linalg.norm(ours - theirs.translation())))
        return worst


def drake_kinematic_solve(
    drake: DrakeScene,
    robot: Any,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    *,
    margin: float,
    n_samples: int,
    control_points: int,
    solver_name: str,
) -> dict[str, Any]:
    """Drake's KinematicTrajectoryOptimization around the scene: a kinematic reference.

    Minimum duration plus path length over a cubic B-spline path with
    ``control_points`` control points; position and velocity bounds of the
    URDF; the path at rest at both ends; ``MinimumDistanceLowerBoundConstraint``
    (``margin``, our robot-vs-scene pairs through the filters) at ``n_samples``
    evenly spaced path parameters. No dynamics, no torque limits.
    """
    from pydrake.multibody.inverse_kinematics import MinimumDistanceLowerBoundConstraint
    from pydrake.planning import KinematicTrajectoryOptimization
    from pydrake.solvers import IpoptSolver, SnoptSolver

    plant, nq = drake.plant, drake.nq
    start, goal = drake.to_drake(q_start), drake.to_drake(q_goal)

    def build() -> tuple[Any, Any]:
        trajopt = KinematicTrajectoryOptimization(nq, control_points, spline_order=4)
        prog = trajopt.get_mutable_prog()
        trajopt.AddDurationCost(1.0)
        trajopt.AddPathLengthCost(1.0)
        trajopt.AddPositionBounds(plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits())
        trajopt.AddVelocityBounds(plant.GetVelocityLowerLimits(), plant.GetVelocityUpperLimits())
        trajopt.AddDurationConstraint(0.05, 10.0)
        trajopt.AddPathPositionConstraint(start, start, 0)
        trajopt.AddPathPositionConstraint(goal, goal, 1)
        trajopt.AddPathVelocityConstraint(np.zeros(nq), np.zeros(nq), 0)
        trajopt.AddPathVelocityConstraint(np.zeros(nq), np.zeros(nq), 1)
        constraint = MinimumDistanceLowerBoundConstraint(
            plant, margin, drake.plant_context, None, 0.05
        )
        for s in np.linspace(0, 1, n_samples):
            trajopt.AddPathPositionConstraint(constraint, s)
        guess = np.linspace(start, goal, control_points).T
        prog.SetInitialGuess(trajopt.control_points(), guess)
        prog.SetInitialGuess(trajopt.duration(), 2.0)
        return trajopt, prog

    (trajopt, prog), build_wall, _ = _timed(build)
    solver = SnoptSolver() if solver_name == "snopt" else IpoptSolver()
    result, wall, cpu = _timed(lambda: solver.Solve(prog))
    path = trajopt.ReconstructTrajectory(result)
    return {
        "solver": solver_name,
        "success": bool(result.is_success()),
        "build_s": build_wall,
        "wall_s": wall,
        "cpu_s": cpu,
        "duration_s": float(path.end_time() - path.start_time()),
        "motion": lambda t: drake.from_drake(path.value(t).ravel()),
        "t_end": float(path.end_time()),
        "t_start": float(path.start_time()),
    }


class DrakeDircol:
    """Drake's ``DirectCollocation`` of our dynamic problem around the scene (one per cell).

    The same problem as ours as far as Drake's transcription allows:

    * **dynamics**: a ``MultibodyPlant`` parsed from the text ``drake`` parsed
      (:attr:`DrakeScene.urdf`: the same bodies, inertias, joint damping,
      locked joints welded, root welded), gravity on, one ``JointActuator``
      per joint of our model (the parser makes one only for a joint with a
      ``<transmission>``: the ur5's, not the panda's), no collision geometry:
      the scene's plant is continuous, and a continuous plant with geometry
      computes contact forces from its ``SceneGraph`` inside the dynamics,
      which ours has not; ``dynamics_error`` is the largest
      ``|a_drake - a_pinocchio|`` over random states (damping included);
    * **transcription**: ``n_knots`` knots, equal free steps in ``[dt_min,
      min(dt_max, 1 s)]`` (ours: ``[dt_min, dt_max]``, unbounded above by
      default; Drake needs a finite step), cubic Hermite states and a
      first-order-hold torque with the dynamics collocated at the interval
      midpoints (Hermite-Simpson, compressed; ours is separated with a free
      midpoint torque);
    * **bounds**: our position, velocity and torque limits at scale 1 (the
      problem's :meth:`bounds`) at every knot (ours also bounds the Bernstein
      control points of the position and velocity cubics between knots);
      start and goal at rest;
    * **objective**: ``beta T + (1 - beta) W``, ``beta`` 0.5. ``cost="simpson"``
      (default): ``W = sum_i h/6 (u_i.u_i + 4 u_m.u_m + u_{i+1}.u_{i+1})`` with
      ``u_m`` the mean of the knot torques (Drake's midpoint torque): our
      Simpson rule on Drake's torque, i.e. the exact integral of its
      piecewise-linear torque, added as ``prog.AddCost`` per interval;
      ``cost="trapezoid"``: ``AddRunningCost(u.u)``, Drake's own running cost
      (the trapezoidal rule over the knots);
    * **clearance**: ``MinimumDistanceLowerBoundConstraint`` (``margin``,
      influence distance ``margin + 0.05`` m, our robot-vs-scene pairs through
      the scene's filters) on the positions of every knot (ours: knots and
      midpoints).

    The program is built once; :meth:`solve` sets the start and goal and the
    guess: the straight joint-space line over 4.9 s (our default guess,
    ``straight_line_guess``: constant velocity, inverse-dynamics torques).
    """

    def __init__(
        self,
        drake: DrakeScene,
        problem: Any,
        *,
        margin: float,
        beta: float = BETA,
        cost: str = "simpson",
        ipopt_tol: float = 1e-8,
    ) -> None:
        import pinocchio as pin
        from pydrake.multibody.inverse_kinematics import MinimumDistanceLowerBoundConstraint
        from pydrake.multibody.parsing import Parser
        from pydrake.multibody.plant import MultibodyPlant
        from pydrake.planning import DirectCollocation
        from pydrake.solvers import IpoptSolver, SolverOptions

        if cost not in ("simpson", "trapezoid"):
            raise ValueError(f"cost must be simpson or trapezoid, got {cost!r}")
        robot = problem.robot
        plant = MultibodyPlant(0.0)
        (instance,) = Parser(plant).AddModelsFromString(drake.urdf, "urdf")
        root = _root_link(drake.urdf)
        if root != "world":
            plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(root, instance))
        names = [robot.model.names[j] for j in range(1, robot.model.njoints)]
        actuated = {
            plant.get_joint_actuator(a).joint().name() for a in plant.GetJointActuatorIndices()
        }
        self.added_actuators = [n for n in names if n not in actuated]
        for name in self.added_actuators:
            plant.AddJointActuator(f"{name}_actuator", plant.GetJointByName(name, instance))
        plant.Finalize()
        if plant.num_actuators() != len(names):
            raise ValueError(f"{plant.num_actuators()} actuators for {len(names)} joints")
        joints = [plant.GetJointByName(n, instance) for n in names]
        if [j.position_start() for j in joints] != list(drake.order):
            raise ValueError("the dynamics plant's joint order differs from the scene's")
        if any(j.velocity_start() != j.position_start() for j in joints):
            raise ValueError("a joint's velocity index differs from its position index")
        by_joint = {
            plant.get_joint_actuator(a).joint().name(): plant.get_joint_actuator(a).input_start()
            for a in plant.GetJointActuatorIndices()
        }
        self.u_order = np.array([by_joint[n] for n in names])  # our joint j -> Drake's input
        self.plant, self.drake, self.problem, self.beta = plant, drake, problem, beta
        self.nq = nq = plant.num_positions()
        self.cost = cost

        # the same robot: forward dynamics against Pinocchio's (with our damping)
        model = robot.model
        data = model.createData()
        damping = np.asarray(robot.damping, dtype=float) if problem.damping else 0.0
        context = plant.CreateDefaultContext()
        rng = np.random.default_rng(0)
        err = 0.0
        for _ in range(5):
            q, v, tau = (rng.uniform(-1.0, 1.0, nq) for _ in range(3))
            plant.SetPositions(context, drake.to_drake(q))
            plant.SetVelocities(context, drake.to_drake(v))
            plant.get_actuation_input_port().FixValue(context, self._u(tau))
            a = drake.from_drake(plant.EvalTimeDerivatives(context).CopyToVector()[nq:])
            err = max(err, float(np.max(np.abs(a - pin.aba(model, data, q, v, tau - damping * v)))))
        self.dynamics_error = err

        n = problem.n_knots
        self.dt_max = min(problem.dt_max, 1.0)  # Drake needs a finite step (T <= 15 s at 16 knots)
        dircol = DirectCollocation(
            plant, plant.CreateDefaultContext(), n, problem.dt_min, self.dt_max,
            plant.get_actuation_input_port().get_index(),
        )  # fmt: skip
        prog = dircol.prog()
        dircol.AddEqualTimeIntervalsConstraints()
        b = problem.bounds(1.0)
        x_lo = np.concatenate([drake.to_drake(b.q_lower), drake.to_drake(b.v_lower)])
        x_hi = np.concatenate([drake.to_drake(b.q_upper), drake.to_drake(b.v_upper)])
        u_lo, u_hi = self._u(b.tau_lower), self._u(b.tau_upper)
        for k in range(n):
            prog.AddBoundingBoxConstraint(x_lo, x_hi, dircol.state(k))
            prog.AddBoundingBoxConstraint(u_lo, u_hi, dircol.input(k))
        rest = np.zeros(2 * nq)
        self.ends = [
            prog.AddBoundingBoxConstraint(rest, rest, dircol.initial_state()),
            prog.AddBoundingBoxConstraint(rest, rest, dircol.final_state()),
        ]
        if cost == "simpson":
            for i in range(n - 1):
                u0, u1 = dircol.input(i), dircol.input(i + 1)
                um = 0.5 * (u0 + u1)
                h = np.ravel(dircol.time_step(i))[0]
                prog.AddCost((1.0 - beta) * h / 6.0 * (u0.dot(u0) + 4.0 * um.dot(um) + u1.dot(u1)))
        else:
            u = dircol.input()
            dircol.AddRunningCost((1.0 - beta) * u.dot(u))
        dircol.AddFinalCost(beta * dircol.time()[0])
        self.clearance = MinimumDistanceLowerBoundConstraint(
            drake.plant, margin, drake.plant_context, None, 0.05
        )
        for k in range(n):
            prog.AddConstraint(self.clearance, dircol.state(k)[:nq])
        self.dircol, self.prog = dircol, prog
        self.ipopt_options = SolverOptions()
        self.ipopt_options.SetOption(IpoptSolver.id(), "tol", float(ipopt_tol))

    def _u(self, tau: np.ndarray) -> np.ndarray:
        """Our torques (our joint order) as Drake's actuation input."""
        out = np.zeros(len(self.u_order))
        out[self.u_order] = tau
        return out

    def objective(self, times: np.ndarray, u: np.ndarray) -> tuple[float, float]:
        """``(f, W)`` of Drake's plan: ``W`` the exact integral of its piecewise-linear torque."""
        h = np.diff(times)
        u0, u1 = u[:-1], u[1:]
        um = 0.5 * (u0 + u1)
        per = (u0 * u0).sum(axis=1) + 4.0 * (um * um).sum(axis=1) + (u1 * u1).sum(axis=1)
        work = float(np.sum(h / 6.0 * per))
        total = float(times[-1] - times[0])
        return self.beta * total + (1.0 - self.beta) * work, work

    def solve(self, q_start: np.ndarray, q_goal: np.ndarray, solver_name: str) -> dict[str, Any]:
        """One solve from the straight line (SNOPT or IPOPT); the plan and its times."""
        from pydrake.solvers import IpoptSolver, SnoptSolver
        from pydrake.trajectories import PiecewisePolynomial

        from youbot_opt.trajopt.guess import straight_line_guess
        from youbot_opt.trajopt.problem import BoundaryState

        drake, nq = self.drake, self.nq
        zero = np.zeros(nq)
        for binding, q in zip(self.ends, (q_start, q_goal), strict=True):
            x = np.concatenate([drake.to_drake(np.asarray(q, dtype=float)), zero])
            binding.evaluator().set_bounds(x, x)
        line = straight_line_guess(
            self.problem, start=BoundaryState(q=np.asarray(q_start, dtype=float)),
            goal=BoundaryState(q=np.asarray(q_goal, dtype=float)),
        )  # fmt: skip
        t = np.asarray(line.t, dtype=float)
        x_guess = np.vstack(
            [np.array([drake.to_drake(q) for q in line.q]).T,
             np.array([drake.to_drake(v) for v in line.v]).T]
        )  # fmt: skip
        u_guess = np.array([self._u(tau) for tau in line.tau]).T
        self.dircol.SetInitialTrajectory(
            PiecewisePolynomial.FirstOrderHold(t, u_guess),
            PiecewisePolynomial.FirstOrderHold(t, x_guess),
        )
        if solver_name == "snopt":
            solver: Any = SnoptSolver()
            options = None
        else:
            solver, options = IpoptSolver(), self.ipopt_options
        result, wall, cpu = _timed(lambda: solver.Solve(self.prog, None, options))
        states = self.dircol.ReconstructStateTrajectory(result)
        times = np.asarray(self.dircol.GetSampleTimes(result), dtype=float)
        u = np.asarray(self.dircol.GetInputSamples(result), dtype=float).T
        f, work = self.objective(times, u)
        return {
            "solver": solver_name,
            "success": bool(result.is_success()),
            "status": str(result.get_solution_result()),
            "wall_s": wall,
            "cpu_s": cpu,
            "duration_s": float(times[-1] - times[0]),
            "f": f,
            "W": work,
            "drake_cost": float(result.get_optimal_cost()),
            "dt_at_max": bool(np.max(np.diff(times)) > self.dt_max * (1 - 1e-6)),
            "motion": lambda s: drake.from_drake(states.value(s)[:nq].ravel()),
            "t_start": float(times[0]),
            "t_end": float(times[-1]),
        }


# -- the benchmark --------------------------------------------------------------------


def _solve_ours(
    robot: Any, clearance: Any, n_knots: int, pair: tuple[np.ndarray, np.ndarray]
) -> dict[str, Any]:
    from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
    from youbot_opt.trajopt.solver import TrajOptSolver

    problem = TrajOptProblem(
        robot=robot,
        start=BoundaryState(q=np.asarray(pair[0], dtype=float)),
        goal=BoundaryState(q=np.asarray(pair[1], dtype=float)),
        n_knots=n_knots,
        clearance=clearance,
    )
    solver, build_wall, _ = _timed(lambda: TrajOptSolver(problem, "hermite_simpson"))
    solver.solve(beta=BETA)  # warm-up: the kernels compile or load
    result, wall, cpu = _timed(lambda: solver.solve(beta=BETA))
    return {
        "result": result, "solver": solver, "build_s": build_wall, "wall_s": wall, "cpu_s": cpu
    }  # fmt: skip


def _start_goal_pairs(
    robot: Any, checker: Any, n: int, seed: int = 28
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Notebook 08's pick and place, then ``n - 1`` seeded perturbations of both.

    Each end is within the joint limits and at least ``MARGIN`` from every
    obstacle by coal (the exact checker); draws that are not are redrawn.
    """
    rng = np.random.default_rng(seed)
    spread = np.array([0.3, 0.2, 0.2, 0.3, 0.3, 0.3])  # [rad]
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    out = [(Q_PICK, Q_PLACE)]
    while len(out) < n:
        ends = [q + rng.uniform(-1, 1, q.shape) * spread for q in (Q_PICK, Q_PLACE)]
        if all(
            np.all(q >= lo) and np.all(q <= hi) and checker.distances(robot, q).min() >= MARGIN
            for q in ends
        ):
            out.append((ends[0], ends[1]))
    return out


def _certify(checker: Any, robot: Any, motion: Any, t0: float, t1: float, n_knots: int) -> Any:
    """One exact checker for every plan: coal distances between samples, the speed bound."""
    from youbot_opt.collision import certify_clearance

    times = np.linspace(t0, t1, 4 * n_knots)
    dense = np.linspace(t0, t1, 400)
    q = np.array([motion(t) for t in dense])
    speeds = np.abs(np.diff(q, axis=0) / np.diff(dense)[:, None]).max(axis=0)
    v_max = np.maximum(np.abs(robot.velocity_limit), 1.1 * speeds)
    return certify_clearance(checker, robot, motion, times, v_max=v_max, margin=MARGIN)


def compare_solves(
    robot: Any,
    checker: Any,
    clearance: Any,
    drake: DrakeScene,
    ours: dict[str, Any],
    *,
    n_knots: int,
    pairs: list[tuple[np.ndarray, np.ndarray]],
    with_refine: bool = True,
    refine_pairs: int | None = None,
    dense: bool = True,
    describe: str = "notebook 08's pick and place and seeded perturbations",
    dircol: bool = True,
    dircol_pairs: int | None = None,
    dircol_cost: str = "simpson",
) -> dict[str, Any]:
    """Ours (with and without the scene) and Drake (kinematic; dynamic) on start/goal pairs.

    Drake's dynamic problem (:class:`DrakeDircol`, SNOPT and IPOPT) runs on the
    first ``dircol_pairs`` pairs (all when ``None``) when ``dircol``.

    Success: the solver says so and one exact checker (coal, the certificate
    of docs/scene.md: samples and the point-speed bound) certifies
    ``MARGIN`` less its 1 mm tolerance over the whole plan; a penetration is
    a plan the solver calls a success whose smallest sampled coal distance is
    negative.
    """
    import dataclasses

    from youbot_opt.exceptions import ParameterError
    from youbot_opt.trajopt.refine import refine
    from youbot_opt.trajopt.solver import TrajOptSolver

    solver = ours["solver"]
    free = TrajOptSolver(dataclasses.replace(solver.problem, clearance=None), "hermite_simpson")
    free.solve(beta=BETA)  # warm-up
    n_points = 2 * n_knots - 1  # knots and Hermite-Simpson midpoints
    rows: dict[str, list[dict[str, Any]]] = {
        "ours": [], "ours, refined (refine())": [], "ours, free space": [],
        "Drake kinematic, snopt": [],
        "Drake kinematic, ipopt": [], f"Drake kinematic, snopt, {4 * n_points} pts": [],
    }  # fmt: skip
    if not with_refine:
        del rows["ours, refined (refine())"]
    if not dense:
        del rows[f"Drake kinematic, snopt, {4 * n_points} pts"]
    dyn: DrakeDircol | None = None
    if dircol:
        dyn, build_wall, _ = _timed(
            lambda: DrakeDircol(
                drake, solver.problem, margin=MARGIN, cost=dircol_cost,
                ipopt_tol=float(solver.options.tol),
            )
        )  # fmt: skip
        rows.update({"Drake dircol, snopt": [], "Drake dircol, ipopt": []})
        print(
            f"Drake DirectCollocation built in {build_wall:.2f} s: {n_knots} knots, "
            f"{dircol_cost} cost, actuators added to {len(dyn.added_actuators)} joints, "
            f"max |a_drake - a_pinocchio| = {dyn.dynamics_error:.1e} rad/s^2",
            flush=True,
        )

    def record(name: str, r: dict[str, Any]) -> None:
        """Add a Drake plan's row, judged by the same certificate as ours."""
        r["ok"] = r.pop("success")
        r["T"] = r["duration_s"]
        r["cert"] = _certify(checker, robot, r.pop("motion"), r["t_start"], r["t_end"], n_knots)
        rows[name].append(r)

    for i, (q0, q1) in enumerate(pairs):
        print(f"pair {i + 1}/{len(pairs)} ...", file=sys.stderr, flush=True)
        runs = [("ours", solver), ("ours, refined (refine())", None), ("ours, free space", free)]
        for name, s in runs:
            if name not in rows or (s is None and refine_pairs is not None and i >= refine_pairs):
                continue
            try:
                if s is None:  # the whole of refine(): round 0's solve, certificates, new grids
                    refined, wall, cpu = _timed(
                        lambda a=q0, b=q1: refine(solver, beta=BETA, start=a, goal=b)
                    )
                    result = refined.result
                else:
                    result, wall, cpu = _timed(
                        lambda s=s, a=q0, b=q1: s.solve(beta=BETA, start=a, goal=b)
                    )
            except ParameterError as exc:  # an end the NLP cannot hold (its balls): refused
                print(f"{name}, pair {i}: refused: {exc}", file=sys.stderr, flush=True)
                rows[name].append(
                    {"ok": False, "refused": str(exc), "wall_s": np.nan, "cpu_s": np.nan,
                     "T": np.nan, "cert": None, "f": np.nan}
                )  # fmt: skip
                continue
            plan = result.trajectory
            t = np.asarray(plan.t, dtype=float)
            cert = _certify(checker, robot, plan, float(t[0]), float(t[-1]), n_knots)
            rows[name].append(
                {"ok": bool(result.success), "wall_s": wall, "cpu_s": cpu,
                 "T": float(t[-1] - t[0]), "cert": cert, "f": float(result.objective)}
            )  # fmt: skip
        for solver_name, n_s in (("snopt", 1), ("ipopt", 1), ("snopt", 4)):
            name = f"Drake kinematic, {solver_name}" + (f", {4 * n_points} pts" if n_s > 1 else "")
            if name not in rows:
                continue
            try:
                r = drake_kinematic_solve(
                    drake, robot, q0, q1, margin=MARGIN, n_samples=n_s * n_points,
                    control_points=n_knots, solver_name=solver_name,
                )  # fmt: skip
            except Exception as exc:  # noqa: BLE001 - a solver not built in, reported
                print(f"{name}: not run ({exc})")
                continue
            record(name, r)
        for solver_name in ("snopt", "ipopt"):
            if dyn is None or (dircol_pairs is not None and i >= dircol_pairs):
                continue
            name = f"Drake dircol, {solver_name}"
            try:
                r = dyn.solve(q0, q1, solver_name)
            except Exception as exc:  # noqa: BLE001 - a solver not built in, reported
                print(f"{name}: not run ({exc})")
                continue
            record(name, r)
        for name, rs in rows.items():  # one line per plan: a run cut short keeps its pairs
            if len(rs) == i + 1:
                r = rs[-1]
                cert = r["cert"]
                line = {"pair": i, "solver": name, "ok": bool(r["ok"]),
                        "certified": cert is not None and bool(cert.certified),
                        "closest_m": None if cert is None else float(cert.closest_distance),
                        "wall_s": r["wall_s"], "cpu_s": r["cpu_s"], "T": r["T"], "f": r.get("f"),
                        "refused": r.get("refused"), "status": r.get("status")}  # fmt: skip
                print("plan " + json.dumps(line), flush=True)
    print(
        f"\nSolves around the scene: {len(pairs)} start/goal pairs ({describe}, "
        f"both ends >= {MARGIN} m by coal), margin {MARGIN} m, "
        f"{n_points} constrained points per plan. ok: the solver's success and coal's "
        "certificate of the margin (less 1 mm) over the whole plan, the same exact checker for "
        "all; penetr. and min clearance: over the plans the solver calls a success."
    )
    print(
        f"{'':<32} {'ok':>6} {'solver ok':>9} {'penetr.':>7} {'wall [s]':>9} {'CPU [s]':>8} "
        f"{'T [s]':>6} {'f':>7} {'min clearance [m]':>18}"
    )
    summary: dict[str, Any] = {"pairs": len(pairs), "n_points": n_points}
    base = base_cpu = None
    refusals = []
    for name, every in rows.items():
        if not every:
            continue
        rs = [r for r in every if r["cert"] is not None]  # solved (refused: no plan)
        if len(rs) < len(every):
            refusals.append(f"{name}: {len(every) - len(rs)} of {len(every)} pairs refused")
        if not rs:
            continue
        ok = sum(r["ok"] and r["cert"].certified for r in rs)
        solver_ok = sum(r["ok"] for r in rs)
        pen = sum(r["ok"] and r["cert"].closest_distance < 0 for r in rs)
        wall = statistics.median(r["wall_s"] for r in rs)
        cpu = statistics.median(r["cpu_s"] for r in rs)
        dur = statistics.median(r["T"] for r in rs)
        f = f"{statistics.median(r['f'] for r in rs):>7.3f}" if "f" in rs[0] else f"{'-':>7}"
        lowest = min((r["cert"].closest_distance for r in rs if r["ok"]), default=np.nan)
        base = base or wall
        base_cpu = base_cpu or cpu
        summary[name] = {"n": len(every), "ok": ok, "solver_ok": solver_ok, "penetrations": pen,
                         "refused": len(every) - len(rs),
                         "median_wall_s": wall, "median_cpu_s": cpu, "median_T_s": dur,
                         "f": f.strip(), "min_clearance_m": lowest}  # fmt: skip
        if "status" in rs[0]:  # Drake dircol: how each solve ended, and a step at its bound
            statuses = [r["status"] for r in rs]
            summary[name]["statuses"] = {k: statuses.count(k) for k in sorted(set(statuses))}
            summary[name]["dt_at_max"] = sum(r["dt_at_max"] for r in rs)
        print(
            f"{name:<32} {ok:>3}/{len(every):<2} {solver_ok:>9} {pen:>7} {wall:>9.3f} {cpu:>8.3f} "
            f"{dur:>6.3f} {f} {lowest:>18.5f}   (wall {wall / base:.2f}x, "
            f"CPU {cpu / base_cpu:.2f}x ours)"
        )
    for line in refusals:  # before IPOPT: an end whose bounding balls lack the margin
        print(f"{line} before solving (an end's bounding balls below the margin; medians over "
              "the others)")  # fmt: skip
    print(
        "medians over the pairs; ours keeps the dynamics and torque limits; Drake kinematic has "
        "no dynamics (B-spline path, minimum T + path length): a kinematic reference; Drake "
        "dircol is our dynamic problem in DirectCollocation (clearance at the knots only; "
        "f = beta T + (1 - beta) W for ours and dircol)"
    )
    if dyn is not None:
        summary["dircol"] = {"dynamics_error": dyn.dynamics_error, "cost": dyn.cost,
                             "added_actuators": dyn.added_actuators}  # fmt: skip
    scene_rows, free_rows = rows["ours"], rows["ours, free space"]
    if scene_rows and free_rows:  # what the scene costs, pair by pair (medians of the ratios)
        both = [(a, b) for a, b in zip(scene_rows, free_rows, strict=True) if a["cert"] is not None]
        cost = {
            key: statistics.median(a[key] / b[key] for a, b in both) if both else np.nan
            for key in ("wall_s", "T", "f")
        }
        summary["scene_cost"] = cost
        print(
            f"the scene against free space, the same pairs (medians of per-pair ratios): "
            f"solve time {cost['wall_s']:.2f}x, motion time T {cost['T']:.2f}x, "
            f"objective {cost['f']:.2f}x"
        )
    return summary


def _closest(d: np.ndarray, pairs: tuple[tuple[str, str], ...]) -> tuple[str, float]:
    k = int(np.nanargmin(d))
    return f"{pairs[k][0]} - {pairs[k][1]}", float(d[k])


def _load_robot(name: str) -> Any:
    """The robot as the scenes' pairs were made for (panda: fingers locked), else the zoo's."""
    sys.path.insert(0, str(SCENES_DIR))
    try:
        from make_scenes import ROBOTS, load_robot  # type: ignore[import-not-found]
    finally:
        sys.path.remove(str(SCENES_DIR))
    if name in ROBOTS:
        return load_robot(name)
    from youbot_opt.robot.load import load_model

    return load_model(name)


def _file_pairs(scene: Path, n: int) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """The first ``n`` pairs of ``<scene stem>_pairs.json`` beside the scene file, if any."""
    path = scene.with_name(f"{scene.stem}_pairs.json")
    if not path.is_file():
        return None
    doc = json.loads(path.read_text(encoding="utf-8"))
    return [(np.asarray(a, dtype=float), np.asarray(b, dtype=float)) for a, b in doc["pairs"][:n]]


def run_cell(robot_name: str, path: Path, args: argparse.Namespace, folder: Path) -> dict[str, Any]:
    """One robot in one scene: distances side by side with Drake, then the solves."""
    import pinocchio as pin

    from youbot_opt.collision import Clearance, clearance_checker, load_scene

    robot = _load_robot(robot_name)
    out: dict[str, Any] = {"robot": robot_name, "scene": path.name}
    scene = load_scene(path)
    clearance = Clearance(scene=scene, margin=MARGIN, self_collision=False)
    checker = clearance_checker(robot, clearance)
    pairs = _file_pairs(path, args.first_pair + args.pairs)
    if pairs is not None:
        pairs = pairs[args.first_pair :]
    describe = f"the seeded pairs of {path.stem}_pairs.json from pair {args.first_pair}"
    if pairs is None:  # notebook 08's pick and place (ur5's joints)
        if robot_name != ROBOT:
            raise SystemExit(f"bench_scene: no {path.stem}_pairs.json for {robot_name}")
        pairs = _start_goal_pairs(robot, checker, max(args.pairs, 1))
        describe = "notebook 08's pick and place and seeded perturbations"
    sub = folder / f"{robot_name}_{path.stem}"
    sub.mkdir(exist_ok=True)
    drake, drake_build, _ = _timed(lambda: DrakeScene(robot, checker, sub))
    scene_pairs = drake.pairs
    print(
        f"\n=== {robot_name} in {path.name}: {len(scene.obstacles)} obstacles, "
        f"{len(scene_pairs)} robot-vs-scene pairs, {robot.model.nq} joints"
        + (f" (locked: {dict(robot.locked_joints)})" if robot.locked_joints else "")
        + f"; Drake diagram built in {drake_build:.2f} s",
        flush=True,
    )

    ours = _solve_ours(robot, clearance, args.knots, pairs[0])
    plan = ours["result"].trajectory
    t = np.asarray(plan.t, dtype=float)
    k = args.samples + 1
    times = np.concatenate(
        [np.linspace(t[i], t[i + 1], k + 1)[:-1] for i in range(len(t) - 1)] + [t[-1:]]
    )
    qs = np.asarray(plan(times), dtype=float)
    frames = [
        f.name
        for f in robot.model.frames
        if f.type == pin.FrameType.BODY and drake.plant.HasFrameNamed(f.name)
    ]
    pose_err = drake.link_pose_error(robot, frames, qs[:: max(len(qs) // 10, 1)])

    coal_d = np.array([checker.distances(robot, q) for q in qs])
    drake_d = np.array([drake.distances(q) for q in qs])
    diff = np.abs(coal_d - drake_d)
    worst = np.unravel_index(int(np.nanargmax(diff)), diff.shape)
    agree = int(sum(np.argmin(a) == np.nanargmin(b) for a, b in zip(coal_d, drake_d, strict=True)))
    i_min = int(np.argmin(coal_d.min(axis=1)))
    ours_pair, ours_min = _closest(coal_d[i_min], scene_pairs)
    j_min = int(np.nanargmin(np.nanmin(drake_d, axis=1)))
    drake_pair, drake_min = _closest(drake_d[j_min], scene_pairs)

    cpu_ours, cpu_drake, wall_ours, wall_drake = [], [], [], []
    for _ in range(args.repeats):  # alternating passes, same machine state
        _, w, c = _timed(lambda: [checker.distances(robot, q) for q in qs])
        wall_ours.append(w / len(qs))
        cpu_ours.append(c / len(qs))
        _, w, c = _timed(lambda: [drake.distances(q) for q in qs])
        wall_drake.append(w / len(qs))
        cpu_drake.append(c / len(qs))
    per_ours, per_drake = statistics.median(wall_ours), statistics.median(wall_drake)
    out["distances"] = {
        "configurations": len(qs),
        "pairs": len(scene_pairs),
        "max_abs_diff_m": float(np.nanmax(diff)),
        "worst_pair": " - ".join(scene_pairs[worst[1]]),
        "frame_position_error_m": pose_err,
        "same_closest_pair": agree,
        "ours_closest": [ours_pair, ours_min, float(times[i_min])],
        "drake_closest": [drake_pair, drake_min, float(times[j_min])],
        "ours_s_per_config": per_ours,
        "drake_s_per_config": per_drake,
        "ours_cpu_per_config": statistics.median(cpu_ours),
        "drake_cpu_per_config": statistics.median(cpu_drake),
    }
    print(
        f"\nDistances at {len(qs)} configurations ({len(t)} knots of our plan of the first pair "
        f"and {args.samples} samples between each two), {len(scene_pairs)} pairs each; "
        f"{len(frames)} frames agree to {pose_err:.1e} m"
    )
    print(f"{'':<32} {'ours (coal)':>24} {'Drake (SceneGraph)':>24}")
    worst_pair = out["distances"]["worst_pair"]
    print(f"{'max |ours - Drake| [m]':<32} {np.nanmax(diff):>49.2e}   ({worst_pair})")
    print(f"{'closest pair':<32} {ours_pair:>24} {drake_pair:>24}")
    print(f"{'  its distance [m]':<32} {ours_min:>24.5f} {drake_min:>24.5f}")
    print(f"{'same closest pair per config':<32} {agree:>49d} / {len(qs)}")
    print(
        f"{'time per configuration [us]':<32} {1e6 * per_ours:>24.1f} {1e6 * per_drake:>24.1f}"
        f"   (Drake / ours {per_drake / per_ours:.2f}x, wall, median of {args.repeats})"
    )
    print(
        f"{'  CPU per configuration [us]':<32} {1e6 * statistics.median(cpu_ours):>24.1f} "
        f"{1e6 * statistics.median(cpu_drake):>24.1f}",
        flush=True,
    )
    if not args.no_solve:
        out["solves"] = compare_solves(
            robot, checker, clearance, drake, ours, n_knots=args.knots, pairs=pairs,
            with_refine=not args.no_refine, refine_pairs=args.refine_pairs,
            dense=not args.no_dense, describe=describe, dircol=not args.no_dircol,
            dircol_pairs=args.dircol_pairs, dircol_cost=args.dircol_cost,
        )  # fmt: skip
    return out


def print_summary(cells: list[dict[str, Any]]) -> None:
    """One table over the cells: per cell and solver, success, penetrations, median times."""
    print(
        "\n=== Summary: ok = the solver's success and coal's certificate of the margin over the "
        "whole plan; penetr. = solver-successful plans with a coal distance < 0 between knots; "
        "times: medians over the pairs"
    )
    print(
        f"{'cell':<26} {'solver':<34} {'ok':>7} {'solver ok':>9} {'penetr.':>7} {'wall [s]':>9} "
        f"{'CPU [s]':>8} {'CPU / ours':>10} {'T [s]':>6} {'f':>7}"
    )
    for cell in cells:
        solves = cell.get("solves", {})
        name = f"{cell['robot']} {Path(cell['scene']).stem.split('_', 1)[-1]}"
        ours_cpu = solves.get("ours", {}).get("median_cpu_s", np.nan)
        for solver, row in solves.items():
            if not isinstance(row, dict) or "ok" not in row:
                continue
            print(
                f"{name:<26} {solver:<34} {row['ok']:>3}/{row['n']:<3} {row['solver_ok']:>9} "
                f"{row['penetrations']:>7} {row['median_wall_s']:>9.3f} "
                f"{row['median_cpu_s']:>8.3f} {row['median_cpu_s'] / ours_cpu:>9.2f}x "
                f"{row['median_T_s']:>6.3f} {row['f']:>7}"
            )
        if "scene_cost" in solves:
            cost = solves["scene_cost"]
            print(
                f"{name:<26} {'scene / free space (ours, per pair)':<34} "
                f"time {cost['wall_s']:.2f}x, T {cost['T']:.2f}x, objective {cost['f']:.2f}x"
            )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 knots, 2 pairs, no refine")
    parser.add_argument("--scene", type=Path, help="scene file (default: notebook 08's cell)")
    parser.add_argument("--robot", default=ROBOT, help="ur5 or panda (fingers locked), ...")
    parser.add_argument(
        "--all", action="store_true", help="{ur5, panda} x {pillar, shelf} of benchmarks/scenes"
    )
    parser.add_argument("--robots", default="ur5,panda", help="--all's robots")
    parser.add_argument("--knots", type=int, default=16)
    parser.add_argument("--samples", type=int, default=4, help="samples between two knots")
    parser.add_argument("--repeats", type=int, default=5, help="timing passes")
    parser.add_argument("--pairs", type=int, default=None, help="start/goal pairs (10; --all 20)")
    parser.add_argument(
        "--first-pair", type=int, default=0, help="skip the pairs file's first K pairs"
    )
    parser.add_argument("--no-solve", action="store_true", help="skip the solve comparison")
    parser.add_argument("--no-refine", action="store_true", help="skip refine() (slow)")
    parser.add_argument(
        "--refine-pairs", type=int, default=None, help="refine() on the first N pairs only"
    )
    parser.add_argument("--no-dense", action="store_true", help="skip Drake SNOPT at 4x samples")
    parser.add_argument(
        "--no-dircol", action="store_true", help="skip Drake's DirectCollocation (dynamic problem)"
    )
    parser.add_argument(
        "--dircol-pairs", type=int, default=None, help="DirectCollocation on the first N pairs only"
    )
    parser.add_argument(
        "--dircol-cost", choices=("simpson", "trapezoid"), default="simpson",
        help="DirectCollocation's W: Simpson on its torque (default) or AddRunningCost",
    )  # fmt: skip
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.pairs is None:
        args.pairs = 20 if args.all else 10
    if args.quick:
        args.knots, args.samples, args.repeats, args.pairs = 10, 1, 2, 2
        args.no_refine = True
    try:
        import pydrake  # noqa: F401
    except ImportError as exc:
        print(f"bench_scene: pydrake is not installed ({exc}): {DRAKE_HINT}", file=sys.stderr)
        return 2

    cells: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.all:
            for robot_name in args.robots.split(","):
                for scene in SCENES:
                    path = SCENES_DIR / f"{robot_name}_{scene}.json"
                    cells.append(run_cell(robot_name, path, args, folder))
            print_summary(cells)
        else:
            path = args.scene
            if path is None:
                path = folder / "cell.json"
                path.write_text(json.dumps(CELL), encoding="utf-8")
            cells.append(run_cell(args.robot, path, args, folder))
    if args.json:
        print(json.dumps(cells if args.all else cells[0], default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
