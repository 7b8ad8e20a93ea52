"""Pinocchio geometry objects as meshcat objects.

Primitive coal shapes become meshcat primitives (a capsule becomes a triangle
mesh). Mesh files are embedded only after :mod:`youbot_opt.robot.urdf_check.meshes`
accepts them (by the loader's own resource policy): STL, OBJ and PLY (sent as
STL) files as ``_meshfile_geometry`` coloured with the URDF colour, COLLADA
files as ``_meshfile_object`` with their own materials and their textures as
``data:`` URIs. A translucent copy, or a COLLADA mesh
whose URDF material overrides the file's, is drawn from the triangles
Pinocchio (coal) loaded, in the URDF colour and without textures.
Obstacles of a :class:`~youbot_opt.collision.scene.Scene` are drawn
semi-transparent in a colour per kind of shape (:func:`obstacle_command`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import coal
import meshcat.commands as mc
import meshcat.geometry as mg
import meshcat.path
import numpy as np
import pinocchio as pin
import umsgpack

from youbot_opt._typing import Array
from youbot_opt.collision.shapes import Box, Capsule, Cylinder, HalfSpace, Shape, Sphere
from youbot_opt.exceptions import ModelError
from youbot_opt.robot.urdf_check.geometry_cache import mesh_loader
from youbot_opt.robot.urdf_check.meshes import load_mesh_file
from youbot_opt.robot.urdf_check.resources import MESH_SUFFIXES

__all__ = [
    "OBSTACLE_COLORS",
    "OBSTACLE_OPACITY",
    "SceneCommand",
    "obstacle_command",
    "set_object_command",
]


class _MeshFileGeometry(mg.Geometry):
    """A mesh file parsed by the viewer (``_meshfile_geometry``), scaled by its intrinsic matrix."""

    def __init__(self, fmt: str, data: bytes, scale: Array) -> None:
        super().__init__()
        self.fmt, self.data, self.scale = fmt, data, scale

    def intrinsic_transform(self) -> Array:
        return self.scale

    def lower(self, object_data: Any) -> dict[str, Any]:
        data = self.data.decode("utf-8") if self.fmt == "obj" else umsgpack.Ext(0x12, self.data)
        return {"uuid": self.uuid, "type": "_meshfile_geometry", "format": self.fmt, "data": data}


class SceneCommand(Protocol):
    """A meshcat command, sent with ``visualizer.window.send``."""

    def lower(self) -> dict[str, object]:
        """Return the command's message (msgpack-ready)."""
        ...


class _ZCylinder(mg.Cylinder):
    """A cylinder along z, as in coal (three.js cylinders are along y)."""

    def intrinsic_transform(self) -> Array:
        return np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])


class _SetColladaObject:
    """``set_object`` of a COLLADA file with its own materials and embedded textures."""

    def __init__(self, text: str, resources: dict[str, str], scale: Array, path: Any) -> None:
        self.text, self.resources, self.scale, self.path = text, resources, scale, path

    def lower(self) -> dict[str, Any]:
        obj = {
            "uuid": mg.SceneElement().uuid,
            "type": "_meshfile_object",
            "format": "dae",
            "data": self.text,
            "resources": self.resources,
            "matrix": list(self.scale.T.flatten()),
        }
        meta = {"version": 4.5, "type": "Object"}
        return {
            "type": "set_object",
            "path": self.path.lower(),
            "object": {"metadata": meta, "geometries": [], "materials": [], "object": obj},
        }


def _rgb(rgba: Sequence[float]) -> int:
    r, g, b = (int(round(255 * min(max(float(c), 0.0), 1.0))) for c in rgba[:3])
    return (r << 16) | (g << 8) | b


def _capsule_mesh(radius: float, half_length: float, n: int = 24) -> tuple[Array, Array]:
    """Vertices and triangles of a capsule along z: two hemispheres joined at their equators."""
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    rings = [
        np.column_stack(
            [
                radius * np.sin(th) * np.cos(phi),
                radius * np.sin(th) * np.sin(phi),
                np.full(n, radius * np.cos(th) + shift),
            ]
        )
        for thetas, shift in (
            (np.linspace(0, np.pi / 2, n // 4 + 1), half_length),
            (np.linspace(np.pi / 2, np.pi, n // 4 + 1), -half_length),
        )
        for th in thetas
    ]
    faces = [
        face
        for r in range(len(rings) - 1)
        for j in range(n)
        for face in (
            [r * n + j, (r + 1) * n + j, r * n + (j + 1) % n],
            [r * n + (j + 1) % n, (r + 1) * n + j, (r + 1) * n + (j + 1) % n],
        )
    ]
    return np.vstack(rings), np.array(faces)


def _bvh_mesh(geom: Any) -> tuple[Array, Array]:
    """Vertices and triangles Pinocchio (coal) loaded from a mesh file, scale applied."""
    faces = [[tri[0], tri[1], tri[2]] for tri in map(geom.tri_indices, range(geom.num_tris))]
    return np.asarray(geom.vertices(), dtype=float), np.array(faces)


def _triangles(go: pin.GeometryObject, cache: dict[tuple[object, ...], object] | None) -> object:
    """Convert the triangles of ``go`` to meshcat geometry, once per (name, file, scale)."""
    if cache is None:
        return mg.TriangularMeshGeometry(*_bvh_mesh(go.geometry))
    key = (go.name, str(go.meshPath), tuple(np.asarray(go.meshScale, dtype=float)))
    if key not in cache:
        cache[key] = mg.TriangularMeshGeometry(*_bvh_mesh(go.geometry))
    return cache[key]


def set_object_command(
    go: pin.GeometryObject,
    package_dirs: Sequence[str | Path],
    opacity: float,
    path: meshcat.path.Path,
    *,
    triangles: dict[tuple[object, ...], object] | None = None,
) -> SceneCommand:
    """Build the meshcat ``set_object`` command that draws one geometry object.

    Parameters
    ----------
    go : pin.GeometryObject
        The geometry object; its pose is sent separately.
    package_dirs : sequence of str or Path
        The robot's package directories, from which mesh files may be embedded.
    opacity : float
        Opacity factor in [0, 1], multiplied with the URDF colour's alpha.
    path : meshcat.path.Path
        Scene path of the object.
    triangles : dict, optional
        Cache of triangle meshes, so that copies of the robot read the
        triangles of each mesh once (keyed by name, mesh file and scale).

    Returns
    -------
    SceneCommand
        A command with ``lower()``, to be sent with ``visualizer.window.send``.

    Raises
    ------
    ModelError
        If a mesh file breaks the mesh policy, or the geometry type is not drawable.
    """
    alpha = float(go.meshColor[3]) * opacity
    material = mg.MeshPhongMaterial(color=_rgb(go.meshColor), opacity=alpha, transparent=alpha < 1)
    geom, mesh_path = go.geometry, str(go.meshPath)
    if Path(mesh_path).suffix:  # a mesh file (primitives are named "BOX", "CYLINDER", ...)
        # the policy decides, for every mesh file; errors name the geometry object
        mesh = load_mesh_file(mesh_path, package_dirs, referenced_by=f"geometry object {go.name!r}")
        scale = np.diag([*np.asarray(go.meshScale, dtype=float), 1.0])
        if mesh.format != "dae":
            return mc.SetObject(_MeshFileGeometry(mesh.format, mesh.data, scale), material, path)
        if alpha == 1.0 and not go.overrideMaterial:
            try:
                text = mesh.data.decode("utf-8")
            except UnicodeDecodeError as e:
                raise ModelError(
                    f"COLLADA file {mesh_path!r} is not UTF-8: {e}", path=mesh_path
                ) from e
            return _SetColladaObject(text, dict(mesh.resources), scale, path)
        if not isinstance(geom, coal.BVHModelBase):
            raise ModelError(
                f"no triangles loaded for {mesh_path!r}; cannot recolour it", path=mesh_path
            )
        return mc.SetObject(_triangles(go, triangles), material, path)
    if isinstance(geom, coal.Box):
        return mc.SetObject(mg.Box(2.0 * np.asarray(geom.halfSide)), material, path)
    if isinstance(geom, coal.Sphere):
        return mc.SetObject(mg.Sphere(geom.radius), material, path)
    if isinstance(geom, coal.Cylinder):
        return mc.SetObject(_ZCylinder(2.0 * geom.halfLength, geom.radius), material, path)
    if isinstance(geom, coal.Capsule):
        mesh_data = _capsule_mesh(geom.radius, geom.halfLength)
        return mc.SetObject(mg.TriangularMeshGeometry(*mesh_data), material, path)
    if isinstance(geom, coal.BVHModelBase):  # triangles built in code, no file
        return mc.SetObject(_triangles(go, triangles), material, path)
    raise ModelError(
        f"geometry {go.name!r} is a {type(geom).__name__}; replay draws mesh files "
        f"({', '.join(MESH_SUFFIXES)}), boxes, spheres, cylinders, capsules and triangle meshes",
        path=mesh_path or None,
    )


#: RGB colour (``0xRRGGBB``) of an obstacle, per kind of shape.
OBSTACLE_COLORS = {
    "Box": 0xA0522D,
    "Sphere": 0x4C72B0,
    "Cylinder": 0x55A868,
    "Capsule": 0xC44E52,
    "HalfSpace": 0x9E9E9E,
    "Mesh": 0x8172B2,
}
OBSTACLE_OPACITY = 0.5  # [-] obstacles are drawn semi-transparent
HALF_SPACE_SIZE = 10.0  # [m] side of the slab that draws a half-space
HALF_SPACE_DEPTH = 0.01  # [m] thickness of that slab, below the plane z = 0


class _Slab(mg.Box):
    """A box whose top face is the plane z = 0 of its frame (a half-space, drawn)."""

    def intrinsic_transform(self) -> Array:
        # meshcat sends the matrix flattened row by row and three.js reads it column by
        # column: the translation goes in the last row
        matrix = np.eye(4)
        matrix[3, 2] = -self.lengths[2] / 2.0
        return matrix


def obstacle_command(shape: Shape, path: meshcat.path.Path) -> SceneCommand:
    """Build the meshcat ``set_object`` command that draws one obstacle shape.

    The shape is drawn in its own frame (its pose is sent separately), in the
    colour of its kind (:data:`OBSTACLE_COLORS`) at :data:`OBSTACLE_OPACITY`; a
    half-space is a thin square slab of :data:`HALF_SPACE_SIZE` [m] under its
    plane, a mesh its triangles as coal reads them, scaled.

    Parameters
    ----------
    shape : Shape
        A :class:`~youbot_opt.collision.shapes.Box`, ``Sphere``, ``Cylinder``,
        ``Capsule``, ``HalfSpace`` or ``Mesh``.
    path : meshcat.path.Path
        Scene path of the object.

    Returns
    -------
    SceneCommand
        A command with ``lower()``, to be sent with ``visualizer.window.send``.
    """
    kind = type(shape).__name__
    material = mg.MeshPhongMaterial(
        color=OBSTACLE_COLORS[kind], opacity=OBSTACLE_OPACITY, transparent=True
    )
    geometry: mg.Geometry
    if isinstance(shape, Box):
        geometry = mg.Box(list(shape.size))
    elif isinstance(shape, Sphere):
        geometry = mg.Sphere(shape.radius)
    elif isinstance(shape, Cylinder):
        geometry = _ZCylinder(shape.length, shape.radius)
    elif isinstance(shape, Capsule):
        geometry = mg.TriangularMeshGeometry(*_capsule_mesh(shape.radius, shape.length / 2.0))
    elif isinstance(shape, HalfSpace):
        geometry = _Slab([HALF_SPACE_SIZE, HALF_SPACE_SIZE, HALF_SPACE_DEPTH])
    else:
        with mesh_loader([shape.path]) as loader:
            bvh = loader.load(str(shape.path), np.array(shape.scale, dtype=float))
        geometry = mg.TriangularMeshGeometry(*_bvh_mesh(bvh))
    return mc.SetObject(geometry, material, path)
