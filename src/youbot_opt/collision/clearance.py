"""Clearance checked with coal's exact geometry: at one configuration and along a motion.

:func:`require_clearance` refuses a configuration (a start, a goal, a target)
closer than the margin, naming the link and the obstacle. :func:`certify_clearance`
certifies a motion between samples: every point of a link moves at most
``V = sum_j v_max_j R_j`` [m/s] (:func:`point_speed_bounds`), so between samples
``dt`` apart a pair keeps ``(d_k + d_{k+1} - (V_a + V_b) dt) / 2``; intervals
where that falls below the margin are bisected until it holds or a sample fails.

>>> require_clearance(checker, robot, q_start, margin=0.01, what="start")  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from youbot_opt._checks import check_end_window, check_nonnegative, check_positive
from youbot_opt._typing import Array, JSONDict
from youbot_opt.collision.exact import ExactChecker, exact_checker
from youbot_opt.collision.model import CollisionModel, build_collision_model
from youbot_opt.collision.pairs import CollisionPairs
from youbot_opt.collision.scene import Scene
from youbot_opt.collision.scene_file import scene_document, scene_from_document
from youbot_opt.collision.spheres import hull_points
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel

__all__ = [
    "DEFAULT_END_WINDOW",
    "Clearance",
    "ClearanceCertificate",
    "clearance_checker",
    "clearance_document",
    "clearance_from_document",
    "collision_model",
    "certify_clearance",
    "point_speed_bounds",
    "require_clearance",
]


#: :attr:`Clearance.end_window`'s default, a fraction of the motion's duration: on the
#: ur5 shelf cell of ``benchmarks/bench_scene.py`` it turned 15 of 20 start/goal pairs
#: refused (their ends' balls within the margin of a board) into solved ones (docs/scene.md).
DEFAULT_END_WINDOW = 0.1


@dataclass(frozen=True, slots=True, kw_only=True)
class Clearance:
    """Clearance a motion must keep from a scene and from the robot itself (#28).

    Plain values, taken by the trajectory problem and the cyclic IK path: the
    optimiser builds the collision model (bounding balls, :func:`collision_model`),
    its CasADi distances and coal's solids (:func:`clearance_checker`) from them.

    Attributes
    ----------
    scene : Scene
        The obstacles (may be empty: self-collision only).
    margin : float
        Required clearance in [m] (>= 0) of every checked pair.
    self_collision : bool
        Also keep the robot's own links apart (the SRDF's active pairs).
    pairs : CollisionPairs or None
        The self-collision pairs; the shipped SRDF's when None.
    end_window : float
        Trajectory problems only (a cyclic IK path has no fixed ends): the
        fraction of the motion's duration, in [0, 0.5], over which a pair whose
        bounding balls are closer than ``margin`` at the fixed start (or goal)
        must reach it. The NLP holds such a pair's ball distance at or above the
        straight ramp from its value at that end (at normalised time 0, or 1) to
        the margin (at ``end_window``, or ``1 - end_window``); coal's exact
        distance at the ends must still keep the margin, and coal's certificate
        judges the plan between and at its points as everywhere. 0 holds the
        margin at the ends too, and refuses an end whose balls lack it (the
        balls overshoot the geometry by up to a few cm: docs/scene.md).
        Default :data:`DEFAULT_END_WINDOW`.
    """

    scene: Scene = Scene()
    margin: float = 0.0  # [m]
    self_collision: bool = True
    pairs: CollisionPairs | None = None
    end_window: float = DEFAULT_END_WINDOW  # fraction of the duration

    def __post_init__(self) -> None:
        if not isinstance(self.scene, Scene):
            raise ParameterError(
                f"scene must be a Scene, got {type(self.scene).__name__}", name="scene"
            )
        object.__setattr__(self, "margin", check_nonnegative(self.margin, "margin", unit="m"))
        object.__setattr__(self, "self_collision", bool(self.self_collision))
        window = check_end_window(self.end_window)
        object.__setattr__(self, "end_window", window)


def collision_model(robot: RobotModel, clearance: Clearance) -> CollisionModel:
    """Return the bounding-ball collision model of ``robot`` in ``clearance``'s scene and pairs."""
    return build_collision_model(
        robot,
        clearance.scene,
        self_collision=clearance.self_collision,
        pairs=clearance.pairs,
    )


def clearance_checker(robot: RobotModel, clearance: Clearance) -> ExactChecker:
    """Return coal's exact solids for the pairs of :func:`collision_model` (the certificate's)."""
    return exact_checker(collision_model(robot, clearance), robot)


def clearance_document(spec: Clearance, folder: Path) -> JSONDict:
    """Describe a :class:`Clearance` for a result file: scene document, margin [m], pairs.

    Mesh paths of the scene are written relative to ``folder`` (the file's folder);
    :func:`clearance_from_document` reads the document back.
    """
    return {
        "scene": scene_document(spec.scene, folder=folder),
        "margin": spec.margin,
        "self_collision": spec.self_collision,
        "pairs": None if spec.pairs is None else [list(p) for p in spec.pairs.active],
        "end_window": spec.end_window,
    }


def clearance_from_document(doc: Mapping[str, object], robot: str, folder: Path) -> Clearance:
    """Return the :class:`Clearance` a :func:`clearance_document` describes.

    A malformed document raises what reading it raises (``KeyError``,
    ``TypeError``, ``ValueError``, :class:`~youbot_opt.exceptions.ParameterError`):
    the file readers turn those into their own file error.

    Parameters
    ----------
    doc : mapping
        The document (``scene``, ``margin`` [m], ``self_collision``, ``pairs``,
        ``end_window``).
    robot : str
        The robot's name, for the active pairs.
    folder : Path
        The result file's folder (relative mesh paths of the scene resolve there).
    """
    pairs = cast("list[tuple[object, object]] | None", doc["pairs"])
    return Clearance(
        scene=scene_from_document(doc["scene"], folder=folder),
        margin=float(cast(float, doc["margin"])),
        self_collision=bool(doc["self_collision"]),
        pairs=None
        if pairs is None
        else CollisionPairs(robot=robot, active=tuple((str(a), str(b)) for a, b in pairs)),
        end_window=float(cast(float, doc["end_window"])),
    )


#: Most exact evaluations one certificate makes before it gives up (a refusal).
_MAX_EVALUATIONS = 200_000


def require_clearance(
    checker: ExactChecker, robot: RobotModel, q: Array, *, margin: float = 0.0, what: str = "q"
) -> None:
    """Refuse a configuration closer than ``margin`` to an obstacle or to the robot itself.

    Parameters
    ----------
    checker : ExactChecker
        The coal solids of the collision model.
    robot : RobotModel
        The robot.
    q : ndarray, shape (nq,)
        The configuration in [rad] or [m].
    margin : float
        Required clearance in [m] (0: no penetration).
    what : str
        What ``q`` is, for the message (``"start"``, ``"goal"``, ``"target 3"``).

    Raises
    ------
    ParameterError
        Naming the closest offending pair (link geometry and obstacle, or two
        link geometries), its distance and the margin; ``name`` is ``what``.
    """
    margin = check_nonnegative(margin, "margin", unit="m")
    d = checker.distances(robot, q)
    bad = np.flatnonzero(d < margin)
    if len(bad) == 0:
        return
    worst = int(bad[np.argmin(d[bad])])
    a, b = checker.model.pair_names[worst]
    kind = "obstacle" if worst >= len(checker.model.self_pairs) else "link geometry"
    state = "penetrates" if d[worst] < 0 else "is closer than the margin to"
    raise ParameterError(
        f"{what}: link geometry {a!r} {state} {kind} {b!r} (distance {d[worst]:.4g} m, "
        f"margin {margin:g} m; {len(bad)} pair(s) in all)",
        name=what,
        value=q,
    )


def _chain(robot: RobotModel, joint: int) -> list[int]:
    """Return the joints from the root to ``joint`` (inclusive), root first."""
    out = []
    while joint > 0:
        out.append(joint)
        joint = int(robot.model.parents[joint])
    return out[::-1]


def point_speed_bounds(checker: ExactChecker, robot: RobotModel, v_max: Array) -> Array:
    """Return a bound [m/s] on the speed of every point of each checked pair's two solids.

    A point of a solid carried by joint ``g`` moves at most ``sum_j v_max_j R_j``
    over the joints ``j`` from the root to ``g``, where for a revolute joint
    ``R_j`` bounds its distance to the point (the norms of the joint
    placements from ``j`` to ``g``, plus prismatic travel, plus the solid's
    reach from ``g``'s origin through its bounding balls) and for a prismatic
    joint ``R_j = 1``. The pair's bound is the sum of its two solids' bounds.

    Parameters
    ----------
    checker : ExactChecker
        The checked pairs.
    robot : RobotModel
        The robot (one degree of freedom per joint).
    v_max : ndarray, shape (nv,)
        Joint speed bounds in [rad/s] or [m/s] the motion respects.

    Returns
    -------
    ndarray, shape (n_pairs,)
        Relative speed bound per pair in [m/s].
    """
    model = robot.model
    v_max = np.abs(np.asarray(v_max, dtype=float))
    prismatic = [
        model.joints[j].shortname().startswith("JointModelP") for j in range(model.njoints)
    ]
    travel = np.maximum(np.abs(model.lowerPositionLimit), np.abs(model.upperPositionLimit))

    def speed(joint: int, reach: float) -> float:
        chain = _chain(robot, joint)
        total = 0.0
        for i, j in enumerate(chain):
            if prismatic[j]:
                total += v_max[model.joints[j].idx_v]
                continue
            radius = reach
            for k in chain[i + 1 :]:
                radius += float(np.linalg.norm(model.jointPlacements[k].translation))
                if prismatic[k]:
                    radius += float(travel[model.joints[k].idx_q])
            total += v_max[model.joints[j].idx_v] * radius
        return total

    cm = checker.model
    link_speed = [
        speed(link.joint, float(np.max(np.linalg.norm(link.centers, axis=1) + link.radii)))
        for link in cm.links
    ]
    obstacle_speed = []
    for placed in cm.obstacles:
        if placed.joint == 0:
            obstacle_speed.append(0.0)
            continue
        points = hull_points(placed.obstacle.shape).points @ placed.rotation.T + placed.translation
        reach = float(np.max(np.linalg.norm(points, axis=1)))
        obstacle_speed.append(speed(placed.joint, reach))
    pairs = [link_speed[a] + link_speed[b] for a, b in cm.self_pairs]
    pairs += [link_speed[a] + obstacle_speed[o] for a, o in cm.scene_pairs]
    return np.array(pairs, dtype=float)


@dataclass(frozen=True, slots=True, kw_only=True)
class ClearanceCertificate:
    """The clearance of a motion, certified between samples.

    Attributes
    ----------
    certified : bool
        Every pair keeps at least ``margin - tolerance`` at every time.
    margin, tolerance : float
        Required clearance and allowed shortfall in [m].
    lower_bound : float
        Certified lower bound on the smallest clearance over the motion in [m]
        (the sampled minimum when not certified).
    closest_pair : tuple of (str, str)
        The pair with the smallest sampled distance.
    closest_time : float
        When it occurs in [s].
    closest_distance : float
        Its exact distance in [m].
    failures : tuple of (float, str, str, float)
        Samples that break ``margin - tolerance``: time [s], pair, distance [m].
    n_samples : int
        Exact evaluations made.
    speed_bound : float
        The largest pair speed bound in [m/s] used between samples.
    """

    certified: bool
    margin: float
    tolerance: float
    lower_bound: float
    closest_pair: tuple[str, str]
    closest_time: float
    closest_distance: float
    failures: tuple[tuple[float, str, str, float], ...]
    n_samples: int
    speed_bound: float


def certify_clearance(
    checker: ExactChecker,
    robot: RobotModel,
    motion: Callable[[float], Array],
    times: Array,
    *,
    v_max: Array,
    margin: float = 0.0,
    tolerance: float = 1e-3,
) -> ClearanceCertificate:
    """Certify a motion's clearance between samples with exact distances and a speed bound.

    Parameters
    ----------
    checker : ExactChecker
        The coal solids and pairs.
    robot : RobotModel
        The robot.
    motion : callable
        ``motion(t)`` -> configuration (nq,) at time ``t`` in [s] (the
        re-simulated motion); its joint speeds never exceed ``v_max``.
    times : ndarray, shape (n,)
        Increasing sample times in [s] to start from (e.g. the knots).
    v_max : ndarray, shape (nv,)
        Joint speed bounds in [rad/s] or [m/s] (the velocity limits the motion
        was certified against).
    margin : float
        Required clearance in [m].
    tolerance : float
        Allowed shortfall in [m] (> 0: it ends the bisection).

    Returns
    -------
    ClearanceCertificate
        Certified, or the failing samples.
    """
    margin = check_nonnegative(margin, "margin", unit="m")
    tolerance = check_positive(tolerance, "tolerance", unit="m")
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or len(times) < 2 or np.any(np.diff(times) <= 0):
        raise ParameterError(
            "times must be >= 2 increasing times in [s]", name="times", value=times
        )
    speeds = point_speed_bounds(checker, robot, v_max)
    names = checker.model.pair_names
    need = margin - tolerance
    evaluations = 0
    closest = (np.inf, 0.0, 0)
    failures: list[tuple[float, str, str, float]] = []
    lower = np.inf

    def sample(t: float) -> Array:
        nonlocal evaluations, closest
        evaluations += 1
        d = checker.distances(robot, np.asarray(motion(t), dtype=float))
        k = int(np.argmin(d)) if len(d) else 0
        if len(d) and d[k] < closest[0]:
            closest = (float(d[k]), t, k)
        for i in np.flatnonzero(d < need):
            failures.append((t, *names[i], float(d[i])))
        return d

    stack = [(float(times[i]), float(times[i + 1])) for i in range(len(times) - 1)][::-1]
    values = {float(t): sample(float(t)) for t in times}
    while stack and evaluations < _MAX_EVALUATIONS:
        t0, t1 = stack.pop()
        d0, d1 = values[t0], values[t1]
        bound = (d0 + d1 - speeds * (t1 - t0)) / 2
        if len(bound) == 0 or np.all(bound >= need) or np.any(d0 < need) or np.any(d1 < need):
            lower = min(lower, float(np.min(bound, initial=np.inf)))
            continue
        tm = (t0 + t1) / 2
        values[tm] = sample(tm)
        stack += [(tm, t1), (t0, tm)]
    exhausted = bool(stack)
    certified = not failures and not exhausted
    return ClearanceCertificate(
        certified=certified,
        margin=margin,
        tolerance=tolerance,
        lower_bound=lower if certified else closest[0],
        closest_pair=names[closest[2]] if names else ("", ""),
        closest_time=closest[1],
        closest_distance=closest[0],
        failures=tuple(failures),
        n_samples=evaluations,
        speed_bound=float(np.max(speeds, initial=0.0)),
    )
