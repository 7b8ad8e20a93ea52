"""The scene: named obstacles, each a shape with a pose, fixed to the world or carried by a frame.

A :class:`Scene` is frozen and composable (``scene + other``,
``scene.with_obstacle(...)``); :func:`furniture` turns the collision geometry
of a URDF file (a table, a shelf) into obstacles through the package's strict
URDF loader. Poses are URDF's ``xyz`` [m] and ``rpy`` [rad] (roll, pitch, yaw
about fixed x, y, z) of the shape's frame in the world frame, or in the frame
named by ``frame`` for an obstacle carried by the robot (a tool, a held box).

>>> scene = Scene() + Obstacle(name="floor", shape=HalfSpace())  # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from youbot_opt._checks import check_finite, shown
from youbot_opt._typing import Array
from youbot_opt.collision.shapes import (
    MAX_SIZE,
    Box,
    Capsule,
    Cylinder,
    HalfSpace,
    Mesh,
    Shape,
    Sphere,
)
from youbot_opt.exceptions import ParameterError

__all__ = ["MAX_OBSTACLES", "Obstacle", "Scene", "furniture"]

#: Most obstacles a scene holds (a file with more is refused).
MAX_OBSTACLES = 1000
_SHAPES = (Box, Sphere, Cylinder, Capsule, HalfSpace, Mesh)


def _triple(values: object, name: str, unit: str, limit: float) -> tuple[float, float, float]:
    """Three finite numbers of magnitude <= ``limit`` from a sequence, else ParameterError."""
    if isinstance(values, str | bytes) or not isinstance(values, Sequence | np.ndarray):
        raise ParameterError(
            f"{name} must be three numbers in [{unit}], got {shown(values)}",
            name=name,
            value=values,
        )
    if len(values) != 3:
        raise ParameterError(
            f"{name} must be three numbers in [{unit}], got {len(values)}: {shown(values)}",
            name=name,
            value=values,
        )
    out = []
    for i, v in enumerate(values):
        x = check_finite(v, f"{name}[{i}]", unit=unit)
        if abs(x) > limit:
            raise ParameterError(
                f"{name}[{i}] must be within ±{limit:g} [{unit}], got {shown(v)}",
                name=f"{name}[{i}]",
                value=v,
            )
        out.append(x)
    return (out[0], out[1], out[2])


@dataclass(frozen=True, slots=True, kw_only=True)
class Obstacle:
    """One named obstacle: a shape and the pose of its frame.

    Attributes
    ----------
    name : str
        Unique name in its scene (error messages and reports use it).
    shape : Shape
        :class:`Box`, :class:`Sphere`, :class:`Cylinder`, :class:`Capsule`,
        :class:`HalfSpace` or :class:`Mesh`.
    xyz : tuple of 3 float
        Position of the shape's frame in [m], in the world or in ``frame``.
    rpy : tuple of 3 float
        Orientation of the shape's frame as roll, pitch, yaw in [rad] (URDF's).
    frame : str or None
        None: fixed to the world. A robot frame's name: carried by that frame.
    """

    name: str
    shape: Shape
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frame: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or len(self.name) > 200:
            raise ParameterError(
                f"name must be a non-empty text of at most 200 characters, got {shown(self.name)}",
                name="name",
                value=self.name,
            )
        if not isinstance(self.shape, _SHAPES):
            raise ParameterError(
                "shape must be a Box, Sphere, Cylinder, Capsule, HalfSpace or Mesh, "
                f"got {shown(self.shape)}",
                name="shape",
                value=self.shape,
            )
        if self.frame is not None and (not isinstance(self.frame, str) or not self.frame):
            raise ParameterError(
                f"frame must be a frame name or None (the world), got {shown(self.frame)}",
                name="frame",
                value=self.frame,
            )
        object.__setattr__(self, "xyz", _triple(self.xyz, "xyz", "m", MAX_SIZE))
        object.__setattr__(self, "rpy", _triple(self.rpy, "rpy", "rad", 4 * math.pi))

    @property
    def rotation(self) -> Array:
        """Rotation matrix (3, 3) of the shape's frame in the world (or carrying) frame."""
        return np.asarray(pin.rpy.rpyToMatrix(np.array(self.rpy)), dtype=float)

    @property
    def translation(self) -> Array:
        """Position (3,) of the shape's frame in [m]."""
        return np.array(self.xyz, dtype=float)

    def placed(self, rotation: Array, translation: Array) -> Obstacle:
        """Return the obstacle with its pose composed after ``(rotation, translation)``.

        Parameters
        ----------
        rotation : ndarray, shape (3, 3)
            Rotation of the new parent frame.
        translation : ndarray, shape (3,)
            Position of the new parent frame in [m].

        Returns
        -------
        Obstacle
            The same shape, posed at ``(rotation, translation) * pose``.
        """
        rot = np.asarray(rotation, dtype=float) @ self.rotation
        pos = np.asarray(rotation, dtype=float) @ self.translation + np.asarray(translation)
        rpy = pin.rpy.matrixToRpy(rot)
        xyz = (float(pos[0]), float(pos[1]), float(pos[2]))
        return replace(self, xyz=xyz, rpy=(float(rpy[0]), float(rpy[1]), float(rpy[2])))


@dataclass(frozen=True, slots=True)
class Scene:
    """A frozen set of uniquely named obstacles.

    Attributes
    ----------
    obstacles : tuple of Obstacle
        The obstacles, in the order given; at most :data:`MAX_OBSTACLES`.
    """

    obstacles: tuple[Obstacle, ...] = field(default=())

    def __post_init__(self) -> None:
        obstacles = tuple(self.obstacles)
        for i, obstacle in enumerate(obstacles):
            if not isinstance(obstacle, Obstacle):
                raise ParameterError(
                    f"obstacles[{i}] must be an Obstacle, got {shown(obstacle)}",
                    name=f"obstacles[{i}]",
                    value=obstacle,
                )
        if len(obstacles) > MAX_OBSTACLES:
            raise ParameterError(
                f"a scene holds at most {MAX_OBSTACLES} obstacles, got {len(obstacles)}",
                name="obstacles",
                value=len(obstacles),
            )
        seen: set[str] = set()
        for obstacle in obstacles:
            if obstacle.name in seen:
                raise ParameterError(
                    f"obstacle names must be unique: {obstacle.name!r} appears twice",
                    name="obstacles",
                    value=obstacle.name,
                )
            seen.add(obstacle.name)
        object.__setattr__(self, "obstacles", obstacles)

    def __add__(self, other: Scene | Obstacle) -> Scene:
        """Return the scene with the obstacles of ``other`` (a scene or one obstacle) added."""
        if isinstance(other, Obstacle):
            return Scene((*self.obstacles, other))
        if isinstance(other, Scene):
            return Scene((*self.obstacles, *other.obstacles))
        return NotImplemented

    def __len__(self) -> int:
        """Return the number of obstacles."""
        return len(self.obstacles)

    @property
    def names(self) -> tuple[str, ...]:
        """The obstacles' names, in order."""
        return tuple(o.name for o in self.obstacles)

    def with_obstacle(self, obstacle: Obstacle) -> Scene:
        """Return the scene with ``obstacle`` added (its name must be new)."""
        return self + obstacle

    def obstacle(self, name: str) -> Obstacle:
        """Return the obstacle named ``name``; a ParameterError lists the names otherwise."""
        for o in self.obstacles:
            if o.name == name:
                return o
        raise ParameterError(
            f"no obstacle named {shown(name)}; the scene has {list(self.names)}",
            name="name",
            value=name,
        )


def _geometry_shape(geometry: object, mesh_path: str, scale: Array, where: str) -> Shape:
    """Return the obstacle shape of one coal collision geometry of a URDF."""
    import coal

    if isinstance(geometry, coal.Box):
        return Box(size=tuple(float(2 * h) for h in geometry.halfSide))  # type: ignore[arg-type]
    if isinstance(geometry, coal.Sphere):
        return Sphere(radius=float(geometry.radius))
    if isinstance(geometry, coal.Cylinder):
        return Cylinder(radius=float(geometry.radius), length=float(2 * geometry.halfLength))
    if isinstance(geometry, coal.Capsule):
        return Capsule(radius=float(geometry.radius), length=float(2 * geometry.halfLength))
    if mesh_path and isinstance(geometry, coal.BVHModelBase):
        return Mesh(path=Path(mesh_path), scale=tuple(float(s) for s in scale))  # type: ignore[arg-type]
    raise ParameterError(
        f"{where}: collision geometry {type(geometry).__name__} is not supported "
        "(box, sphere, cylinder, capsule and meshes are)",
        name="urdf",
        value=type(geometry).__name__,
    )


def furniture(
    path: str | os.PathLike[str],
    *,
    name: str,
    xyz: Sequence[float] = (0.0, 0.0, 0.0),
    rpy: Sequence[float] = (0.0, 0.0, 0.0),
    package_dirs: Sequence[str | os.PathLike[str]] = (),
) -> Scene:
    """Return the collision geometry of a URDF file (a table, a shelf) as obstacles.

    The file goes through the strict URDF loader (its folder and ``package_dirs``
    are where meshes may come from); its joints are at their neutral position.
    Each collision geometry becomes an obstacle fixed to the world, named
    ``"<name>/<geometry name>"``.

    Parameters
    ----------
    path : path-like
        The URDF file.
    name : str
        Prefix of the obstacles' names.
    xyz : sequence of 3 float
        Position of the file's root link in the world in [m].
    rpy : sequence of 3 float
        Orientation of the root link as roll, pitch, yaw in [rad].
    package_dirs : sequence of path-like
        Extra folders for ``package://`` references.

    Returns
    -------
    Scene
        One obstacle per collision geometry.

    Raises
    ------
    ModelError
        The file is missing or refused by the strict loader (a URDFError).
    ParameterError
        A pose is not three finite numbers, or a geometry type is not supported.
    """
    from youbot_opt.robot.urdf_check.loader import load_urdf_strict

    root = Obstacle(name=name, shape=HalfSpace(), xyz=tuple(xyz), rpy=tuple(rpy))  # type: ignore[arg-type]
    file = Path(path).absolute()
    loaded = load_urdf_strict(file, (file.parent, *(Path(p) for p in package_dirs)), strict=False)
    data = loaded.model.createData()
    pin.framesForwardKinematics(loaded.model, data, pin.neutral(loaded.model))
    obstacles = []
    for geom in loaded.collision_model.geometryObjects:
        where = f"{file}: collision geometry {geom.name!r}"
        shape = _geometry_shape(geom.geometry, geom.meshPath, np.asarray(geom.meshScale), where)
        placement = data.oMi[geom.parentJoint] * geom.placement
        local = Obstacle(
            name=f"{name}/{geom.name}",
            shape=shape,
            xyz=tuple(float(x) for x in placement.translation),  # type: ignore[arg-type]
            rpy=tuple(float(a) for a in pin.rpy.matrixToRpy(placement.rotation)),  # type: ignore[arg-type]
        )
        obstacles.append(local.placed(root.rotation, root.translation))
    return Scene(tuple(obstacles))
