"""Write the benchmark scenes of issue 28 item 8 and their start/goal pairs (seeded).

Run ``python benchmarks/scenes/make_scenes.py [--pairs 20]`` (no Drake needed).
For each robot (``ur5``, ``panda`` with its fingers locked closed) and each
scene it writes ``<robot>_<scene>.json`` (a scene file of our format,
docs/scene.md) and ``<robot>_<scene>_pairs.json`` (the start/goal pairs, in
the robot's joint order, radians) next to this script:

* ``pick_place_pillar``: a table in front of the robot, its top at the base's
  height, and a pillar standing on it between the pick region (y < 0) and the
  place region (y > 0); both ends hold the tool pointing down above the table.
* ``shelf_reach``: a shelf in front of the robot (two compartments: bottom,
  middle and top boards, two sides, a back wall, all boxes); the start holds
  the tool in front of the shelf or in the other compartment, the goal holds it
  pointing into a compartment, ``DEPTH`` deep.

The scenes are placed from each robot's reach (``REACH``, the distance from
the base at which its tool works comfortably). A pair is kept when both ends
are within the joint limits and at least ``MARGIN`` from every obstacle by coal
(the certificate's exact checker) and the straight joint-space line between
them collides (coal distance < 0 at one of 64 points along it): the obstacle
has to be avoided. The ends are found by damped least-squares IK from seeded
random tool targets in the regions above.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
MARGIN = 0.01  # [m] the benchmark's margin
SEED = 28
#: Robot name -> (load_model keywords, tool frame, reach [m], IK seed posture).
ROBOTS: dict[str, dict[str, Any]] = {
    "ur5": {
        "kwargs": {},
        "tool": "tool0",
        "reach": 0.55,
        "seed_down": [0.0, -1.0, 1.6, -2.1, -1.57, 0.0],
        "seed_forward": [0.0, -1.2, 1.9, -0.7, 1.57, 0.0],
    },
    "panda": {
        # the CLI's way: the finger joint locked (its mimic follows), the arm's 7 joints planned
        "kwargs": {"lock_joints": {"panda_finger_joint1": 0.0}},
        "tool": "panda_hand_tcp",
        "reach": 0.5,
        "seed_down": [0.0, 0.4, 0.0, -2.0, 0.0, 2.4, 0.8],
        "seed_forward": [0.0, 0.2, 0.0, -1.8, 0.0, 3.5, 0.8],
    },
}
SCENES = ("pick_place_pillar", "shelf_reach")
DEPTH = 0.12  # [m] how deep the goal's tool point lies in the compartment


def load_robot(name: str) -> Any:
    """The benchmark's robot: ``load_model(name, **ROBOTS[name]["kwargs"])``."""
    from youbot_opt.robot.load import load_model

    return load_model(name, **ROBOTS[name]["kwargs"])


def _box(name: str, size: list[float], xyz: list[float]) -> dict[str, Any]:
    return {"name": name, "shape": "box", "size": [round(s, 4) for s in size],
            "xyz": [round(v, 4) for v in xyz]}  # fmt: skip


def scene_document(robot: str, scene: str) -> dict[str, Any]:
    """The scene file's content for ``robot`` (placed from its reach)."""
    r = ROBOTS[robot]["reach"]
    if scene == "pick_place_pillar":
        obstacles = [
            _box("table", [0.6, 1.4, 0.04], [r + 0.05, 0.0, -0.02]),
            {"name": "pillar", "shape": "cylinder", "radius": 0.06, "length": 0.6,
             "xyz": [round(r, 4), 0.0, 0.3]},
        ]  # fmt: skip
    elif scene == "shelf_reach":
        front, depth, width, t = r - 0.05, 0.3, 0.7, 0.02
        xc = front + depth / 2
        levels = (0.1, 0.42, 0.74)  # [m] board centres: compartments 0.3 m high
        obstacles = [
            _box(f"board {i}", [depth, width, t], [xc, 0.0, z]) for i, z in enumerate(levels)
        ]
        height = levels[-1] - levels[0] + t
        zc = (levels[-1] + levels[0]) / 2
        obstacles += [
            _box("side left", [depth, t, height], [xc, width / 2 + t / 2, zc]),
            _box("side right", [depth, t, height], [xc, -width / 2 - t / 2, zc]),
            _box("back", [t, width + 2 * t, height], [front + depth + t / 2, 0.0, zc]),
        ]
    else:
        raise ValueError(scene)
    return {"schema": "youbot_opt.scene", "schema_version": 1, "obstacles": obstacles}


def _rotation(direction: str, yaw: float) -> np.ndarray:
    """The tool's orientation: z down (``"down"``) or along +x turned by ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    if direction == "down":  # z = -world z, x along the yaw
        return np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])
    # z along (c, s, 0), x = world -z, y = z cross x
    z = np.array([c, s, 0.0])
    x = np.array([0.0, 0.0, -1.0])
    return np.column_stack([x, np.cross(z, x), z])


def ik(robot: Any, frame: str, rotation: np.ndarray, point: np.ndarray, q0: np.ndarray) -> Any:
    """Damped least-squares IK of ``frame`` to (``rotation``, ``point``); None if not reached."""
    import pinocchio as pin

    model, data = robot.model, robot.create_data()
    fid = robot.frame_id(frame)
    target = pin.SE3(rotation, point)
    q = q0.copy()
    for _ in range(300):
        pin.framesForwardKinematics(model, data, q)
        err = pin.log6(data.oMf[fid].actInv(target)).vector
        if np.linalg.norm(err[:3]) < 1e-5 and np.linalg.norm(err[3:]) < 1e-4:
            return q
        jac = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
        dq = jac.T @ np.linalg.solve(jac @ jac.T + 1e-6 * np.eye(6), err)
        q = np.clip(pin.integrate(model, q, 0.5 * dq), model.lowerPositionLimit,
                    model.upperPositionLimit)  # fmt: skip
    return None


def _target(robot: str, scene: str, end: str, rng: np.random.Generator) -> Any:
    """A random tool target (direction, yaw, point) of ``end`` ("start" or "goal")."""
    r = ROBOTS[robot]["reach"]
    if scene == "pick_place_pillar":
        side = -1.0 if end == "start" else 1.0
        angle = side * rng.uniform(0.35, 0.75)
        radius = r + rng.uniform(-0.1, 0.08)
        point = np.array([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(0.08, 0.2)])
        return "down", angle + rng.uniform(-0.5, 0.5), point
    front = r - 0.05
    if end == "goal":  # into a compartment, the tool along +x
        z = rng.choice([0.26, 0.58]) + rng.uniform(-0.03, 0.03)
        point = np.array([front + DEPTH, rng.uniform(-0.15, 0.15), z])
        return "forward", rng.uniform(-0.2, 0.2), point
    if rng.uniform() < 0.5:  # in front of the shelf, pointing down, low or high
        point = np.array([front - rng.uniform(0.12, 0.25), rng.uniform(-0.4, 0.4),
                          rng.choice([0.0, 0.9]) + rng.uniform(-0.05, 0.05)])  # fmt: skip
        return "down", rng.uniform(-0.5, 0.5), point
    z = rng.choice([0.26, 0.58]) + rng.uniform(-0.03, 0.03)  # in a compartment
    return "forward", rng.uniform(-0.2, 0.2), np.array([front + DEPTH, rng.uniform(-0.15, 0.15), z])


def make_pairs(robot_name: str, scene: str, n: int, seed: int = SEED) -> list[list[list[float]]]:
    """``n`` start/goal pairs for the scene file ``<robot>_<scene>.json`` (module docstring)."""
    from youbot_opt.collision import Clearance, clearance_checker, load_scene

    robot = load_robot(robot_name)
    spec = ROBOTS[robot_name]
    scene_file = HERE / f"{robot_name}_{scene}.json"
    clearance = Clearance(scene=load_scene(scene_file), margin=MARGIN, self_collision=False)
    checker = clearance_checker(robot, clearance)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    rng = np.random.default_rng([seed, SCENES.index(scene), list(ROBOTS).index(robot_name)])

    def end(which: str) -> Any:
        for _ in range(50):
            direction, yaw, point = _target(robot_name, scene, which, rng)
            seed_q = np.asarray(spec["seed_down" if direction == "down" else "seed_forward"])
            q0 = np.clip(seed_q + rng.uniform(-0.3, 0.3, seed_q.shape), lo, hi)
            q0[0] = np.arctan2(point[1], point[0])
            q = ik(robot, spec["tool"], _rotation(direction, yaw), point, q0)
            if q is not None and checker.distances(robot, q).min() >= MARGIN:
                return q
        raise RuntimeError(f"{robot_name} {scene}: no {which} found")

    out: list[list[list[float]]] = []
    while len(out) < n:
        q_start, q_goal = end("start"), end("goal")
        if np.linalg.norm(q_goal - q_start) < 0.3:
            continue
        line = np.linspace(q_start, q_goal, 64)
        if min(checker.distances(robot, q).min() for q in line) < 0:
            out.append([[round(float(v), 6) for v in q] for q in (q_start, q_goal)])
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=20)
    args = parser.parse_args()
    for robot in ROBOTS:
        for scene in SCENES:
            stem = f"{robot}_{scene}"
            doc = scene_document(robot, scene)
            (HERE / f"{stem}.json").write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
            pairs = make_pairs(robot, scene, args.pairs)
            pairs_doc = {"robot": robot, "load_model": ROBOTS[robot]["kwargs"],
                         "scene": f"{stem}.json", "margin_m": MARGIN, "seed": SEED,
                         "pairs": pairs}  # fmt: skip
            (HERE / f"{stem}_pairs.json").write_text(
                json.dumps(pairs_doc, indent=1) + "\n", encoding="utf-8"
            )
            print(f"{stem}: {len(doc['obstacles'])} obstacles, {len(pairs)} pairs", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
