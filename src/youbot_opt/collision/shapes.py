"""Obstacle shapes: box, sphere, cylinder, capsule, half-space and mesh, each in its own frame.

Every shape is centred on its frame's origin; a cylinder's and a capsule's axis
is the frame's z axis (as in URDF and coal); a half-space is the region
``z <= 0`` of its frame. A mesh is a file in a format the URDF loader accepts
(:data:`~youbot_opt.robot.urdf_check.resources.MESH_SUFFIXES`), scaled per axis.
Sizes are in [m]; the constructors refuse non-finite, non-positive or huge sizes.

>>> table_top = Box(size=(1.2, 0.8, 0.04))
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from youbot_opt._checks import check_positive, shown
from youbot_opt.exceptions import ParameterError

__all__ = [
    "MAX_SIZE",
    "Box",
    "Capsule",
    "Cylinder",
    "HalfSpace",
    "Mesh",
    "Shape",
    "Sphere",
]

#: Largest size of a shape along any axis in [m] (a bigger one is a typo or an attack).
MAX_SIZE = 1.0e3


def _size(value: object, name: str) -> float:
    """Return ``value`` as a float in (0, MAX_SIZE] [m], else a ParameterError naming ``name``."""
    x = check_positive(value, name, unit="m")
    if x > MAX_SIZE:
        raise ParameterError(
            f"{name} must be at most {MAX_SIZE:g} [m], got {shown(value)}", name=name, value=value
        )
    return x


def _sizes(values: object, name: str) -> tuple[float, float, float]:
    """Return three sizes [m] from a sequence of three numbers."""
    if (
        isinstance(values, str | bytes)
        or not isinstance(values, Sequence | np.ndarray)
        or len(values) != 3
    ):
        raise ParameterError(
            f"{name} must be three numbers in [m], got {shown(values)}", name=name, value=values
        )
    a, b, c = (_size(v, f"{name}[{i}]") for i, v in enumerate(values))
    return (a, b, c)


@dataclass(frozen=True, slots=True, kw_only=True)
class Box:
    """A rectangular box centred on its frame.

    Attributes
    ----------
    size : tuple of 3 float
        Full edge lengths along x, y, z in [m] (as URDF ``<box size>``).
    """

    size: tuple[float, float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", _sizes(self.size, "size"))


@dataclass(frozen=True, slots=True, kw_only=True)
class Sphere:
    """A ball centred on its frame.

    Attributes
    ----------
    radius : float
        Radius in [m].
    """

    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", _size(self.radius, "radius"))


@dataclass(frozen=True, slots=True, kw_only=True)
class Cylinder:
    """A solid cylinder about the frame's z axis, centred on its frame.

    Attributes
    ----------
    radius : float
        Radius in [m].
    length : float
        Full length along z in [m].
    """

    radius: float
    length: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", _size(self.radius, "radius"))
        object.__setattr__(self, "length", _size(self.length, "length"))


@dataclass(frozen=True, slots=True, kw_only=True)
class Capsule:
    """The points within ``radius`` of a segment on the frame's z axis.

    Attributes
    ----------
    radius : float
        Radius in [m].
    length : float
        Length of the segment (between the two hemispheres' centres) in [m].
    """

    radius: float
    length: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", _size(self.radius, "radius"))
        object.__setattr__(self, "length", _size(self.length, "length"))


@dataclass(frozen=True, slots=True, kw_only=True)
class HalfSpace:
    """The half-space ``z <= 0`` of its frame (a floor, a wall): it has no size."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Mesh:
    """A mesh file, scaled per axis; its solid is the convex hull of its vertices.

    Attributes
    ----------
    path : pathlib.Path
        The mesh file (``.stl``, ``.dae``, ``.obj``, ``.ply``), absolute.
    scale : tuple of 3 float
        Scale factors along x, y, z (dimensionless, > 0).
    """

    path: Path
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        if not isinstance(self.path, str | Path):
            raise ParameterError(
                f"path must be a mesh file path, got {shown(self.path)}",
                name="path",
                value=self.path,
            )
        object.__setattr__(self, "path", Path(self.path).absolute())
        scale = _sizes(self.scale, "scale")
        if not all(math.isfinite(s) for s in scale):  # pragma: no cover - _sizes refuses
            raise ParameterError(f"scale must be finite, got {scale}", name="scale", value=scale)
        object.__setattr__(self, "scale", scale)


#: Any obstacle shape.
Shape = Box | Sphere | Cylinder | Capsule | HalfSpace | Mesh
