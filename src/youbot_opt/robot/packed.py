"""A robot's collision geometry as plain arrays, for sending it to another process (#28).

coal pickles a mesh as a text archive of its vertices, triangles and bounding-volume
tree (ur5's eight collision meshes: 9.9 MB); :func:`pack_geometry` keeps the
vertices and triangles as arrays and the geometry objects' other fields in
Pinocchio's own pickle (0.14 MB), and :meth:`PackedGeometry.unpack` rebuilds the
meshes (coal builds the same tree: the rebuilt model pickles to the same bytes).
A process that packed a model gets that very model back on unpacking.

>>> packed = pack_geometry(robot.collision_model)  # doctest: +SKIP
>>> geometry = pickle.loads(pickle.dumps(packed)).unpack()  # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import pickle
import threading
import weakref
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError

__all__ = ["PackedGeometry", "PackedMesh", "pack_geometry"]


@dataclass(frozen=True, slots=True, kw_only=True)
class PackedMesh:
    """One mesh of a collision geometry model, as arrays.

    Attributes
    ----------
    index : int
        Its geometry object's index in the model.
    kind : type
        Its coal class (``coal.BVHModelOBBRSS`` for the meshes Pinocchio loads).
    vertices : ndarray, shape (n, 3)
        Vertices in [m] in the object's frame (scaled, as coal holds them).
    triangles : ndarray, shape (m, 3), int32
        Vertex indices of each triangle (m = 0: a point cloud).
    """

    index: int
    kind: type
    vertices: Array
    triangles: np.ndarray

    def build(self) -> coal.CollisionGeometry:
        """Return the coal mesh (its bounding-volume tree built again)."""
        mesh = self.kind()
        mesh.beginModel(len(self.triangles), len(self.vertices))
        mesh.addVertices(self.vertices)
        if len(self.triangles):
            mesh.addTriangles(self.triangles)
        mesh.endModel()
        return mesh


@dataclass(frozen=True, slots=True, kw_only=True)
class PackedGeometry:
    """A collision geometry model whose meshes travel as arrays.

    Attributes
    ----------
    shell : pinocchio.GeometryModel
        The model's geometry objects (names, frames, placements, mesh paths,
        scales, colours, collision pairs) with each packed mesh replaced by an
        empty sphere.
    meshes : tuple of PackedMesh
        The meshes, by object index.
    digest : str
        SHA-256 of the shell's pickle and the meshes' arrays (equal digests:
        equal models).
    """

    shell: pin.GeometryModel
    meshes: tuple[PackedMesh, ...]
    digest: str

    def unpack(self) -> pin.GeometryModel:
        """Return the geometry model: this process's own if it packed an equal one, else rebuilt.

        Returns
        -------
        pinocchio.GeometryModel
            Equal to the packed model (its meshes' vertices and triangles the
            same numbers, their trees built again by coal). Treat as read-only:
            the process's problems may share it.
        """
        with _LOCK:
            ref = _MODELS.get(self.digest)
        model = None if ref is None else ref()
        if model is not None:
            return model
        model = pickle.loads(pickle.dumps(self.shell, protocol=5))  # the shell stays as it is
        for mesh in self.meshes:
            model.geometryObjects[mesh.index].geometry = mesh.build()
        _remember(self.digest, model)
        return model


def pack_geometry(model: pin.GeometryModel) -> PackedGeometry:
    """Pack a collision geometry model: its meshes as arrays, the rest as it is.

    Parameters
    ----------
    model : pinocchio.GeometryModel
        The model (a robot's ``collision_model``); not modified.

    Returns
    -------
    PackedGeometry
        What :meth:`PackedGeometry.unpack` rebuilds it from; this process
        remembers ``model`` (weakly) under the digest.

    Raises
    ------
    ParameterError
        If ``model`` is not a ``pinocchio.GeometryModel``.
    """
    if not isinstance(model, pin.GeometryModel):
        raise ParameterError(
            f"model must be a pinocchio.GeometryModel, got {type(model).__name__}",
            name="model",
            value=type(model).__name__,
        )
    shell = pin.GeometryModel()
    meshes = []
    for i, obj in enumerate(model.geometryObjects):
        copy = obj.copy()
        geometry = obj.geometry
        if isinstance(geometry, coal.BVHModelBase) and geometry.convex is None:
            n = geometry.num_tris
            triangles = np.array(
                [[geometry.tri_indices(k)[j] for j in range(3)] for k in range(n)],
                dtype=np.int32,
            ).reshape(n, 3)
            vertices = np.array(geometry.vertices(), dtype=float).reshape(-1, 3)
            meshes.append(
                PackedMesh(index=i, kind=type(geometry), vertices=vertices, triangles=triangles)
            )
            copy.geometry = coal.Sphere(0.0)
        shell.addGeometryObject(copy)
    for pair in model.collisionPairs:
        shell.addCollisionPair(pair)
    digest = hashlib.sha256(pickle.dumps(shell, protocol=5))
    for mesh in meshes:
        digest.update(f"{mesh.index}:{mesh.kind.__name__}".encode())
        digest.update(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes())
        digest.update(np.ascontiguousarray(mesh.triangles, dtype="<i4").tobytes())
    packed = PackedGeometry(shell=shell, meshes=tuple(meshes), digest=digest.hexdigest())
    _remember(packed.digest, model)
    return packed


# The geometry models this process packed or unpacked, by digest (weak references: a
# model dropped frees it), so that unpacking here returns the model itself.
_MODELS: dict[str, weakref.ref[pin.GeometryModel]] = {}
_LOCK = threading.Lock()


def _remember(digest: str, model: pin.GeometryModel) -> None:
    with _LOCK:
        for dead in [k for k, ref in _MODELS.items() if ref() is None]:
            del _MODELS[dead]
        _MODELS[digest] = weakref.ref(model)
