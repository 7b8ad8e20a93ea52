"""Bounding balls of collision geometry, fitted once and cached on disk, with their overshoot.

A solid (a link's geometry or a mesh obstacle) is replaced by its convex hull
(a cylinder by a circumscribed prism), cut by a grid of cells in its principal
axes (slabs along the longest axis, or cells across two or three axes for a
wide solid), and each cell's part enclosed by one ball: the union contains the
solid, so distances to it are conservative. The overshoot [m] is a
rigorous bound on how far a ball's point lies from the hull (the support-function
bound of ``docs/scene.md``). Fits are cached as JSON in :func:`collision_cache_dir`.

>>> fit = fit_spheres(hull_points(Box(size=(0.4, 0.1, 0.1))))  # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from youbot_opt._files import atomic_write_text
from youbot_opt._typing import Array
from youbot_opt.collision.shapes import Box, Capsule, Cylinder, Mesh, Shape, Sphere
from youbot_opt.exceptions import ModelError, ParameterError

__all__ = [
    "DEFAULT_MAX_SPHERES",
    "DEFAULT_TARGET_OVERSHOOT",
    "HullPoints",
    "SphereFit",
    "collision_cache_dir",
    "fit_spheres",
    "geometry_hull",
    "hull_points",
]

_log = logging.getLogger(__name__)

#: Fit overshoot the sphere count is raised to reach, in [m].
DEFAULT_TARGET_OVERSHOOT = 0.01
#: Most spheres fitted to one solid.
DEFAULT_MAX_SPHERES = 16
#: Sides of the prism circumscribing a cylinder's circle.
_PRISM_SIDES = 32
#: Cells per cube face edge of the direction grids (6 (m+1)^2 directions): a
#: coarse one to choose the ball count, a fine one for the reported overshoot.
_COARSE_GRID = 24
_FINE_GRID = 128
#: Iterations of the Badoiu-Clarkson minimum-enclosing-ball centre.
_CENTRE_ITERATIONS = 100
#: Version of the fitting algorithm (part of the cache key).
_FIT_VERSION = 3
#: Overshoot [m] more balls must save to be taken when the target is out of reach.
_WORTH = 0.002
#: Most hull points a solid may have (a bigger mesh is refused).
_MAX_POINTS = 200_000


@dataclass(frozen=True, slots=True, kw_only=True)
class HullPoints:
    """A convex polytope containing a solid, in the solid's own frame.

    Attributes
    ----------
    points : ndarray, shape (n, 3)
        The polytope's vertices in [m].
    slack : float
        Upper bound in [m] on the distance from a point of the polytope to the
        solid (0 when the polytope is the solid, e.g. a box or a mesh's hull).
    sphere : tuple of (ndarray, float) or None
        For a sphere or capsule solid, ``None``; see ``exact``.
    exact : tuple of ndarray or None
        For a sphere: ``(centres (1, 3), radii (1,))``; for a capsule the
        balls on its segment; None for polytopes.
    """

    points: Array
    slack: float = 0.0
    exact: tuple[Array, Array] | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class SphereFit:
    """Balls whose union contains a solid.

    Attributes
    ----------
    centers : ndarray, shape (k, 3)
        Ball centres in [m] in the solid's frame.
    radii : ndarray, shape (k,)
        Ball radii in [m].
    overshoot : float
        Upper bound in [m] on the distance from any point of the balls to the
        solid: a distance to the balls is at most the distance to the solid and
        at least that minus ``overshoot``.
    """

    centers: Array
    radii: Array
    overshoot: float

    def placed(self, rotation: Array, translation: Array) -> SphereFit:
        """Return the balls in a parent frame that holds the solid's frame at a placement."""
        centers = self.centers @ np.asarray(rotation).T + np.asarray(translation)
        return SphereFit(centers=centers, radii=self.radii, overshoot=self.overshoot)


def collision_cache_dir() -> Path:
    """Return the folder of cached sphere fits (not created here)."""
    env = os.environ.get("YOUBOT_OPT_CACHE")
    if env:
        return Path(env) / "collision"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "youbot_opt" / "collision"


def _capsule_balls(radius: float, length: float) -> tuple[Array, Array, float]:
    """Balls covering a capsule: centres on its segment, spacing <= radius."""
    n = max(2, math.ceil(length / radius) + 1)
    z = np.linspace(-length / 2, length / 2, n)
    half = length / (n - 1) / 2
    big = math.hypot(radius, half)
    centers = np.column_stack([np.zeros(n), np.zeros(n), z])
    return centers, np.full(n, big), big - radius


def hull_points(shape: Shape) -> HullPoints:
    """Return a convex polytope containing an obstacle shape (not for a half-space).

    Parameters
    ----------
    shape : Box, Sphere, Cylinder, Capsule or Mesh
        The solid.

    Returns
    -------
    HullPoints
        The polytope's vertices and its slack.

    Raises
    ------
    ParameterError
        For a :class:`HalfSpace` (unbounded).
    ModelError
        A mesh cannot be read.
    """
    if isinstance(shape, Box):
        half = np.array(shape.size) / 2
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return HullPoints(points=corners * half)
    if isinstance(shape, Sphere):
        r = shape.radius
        return HullPoints(points=np.eye(3) * r, exact=(np.zeros((1, 3)), np.array([r])))
    if isinstance(shape, Cylinder):
        return _prism(shape.radius, shape.length)
    if isinstance(shape, Capsule):
        centers, radii, _ = _capsule_balls(shape.radius, shape.length)
        return HullPoints(points=centers, exact=(centers, radii))
    if isinstance(shape, Mesh):
        return HullPoints(points=_mesh_vertices(shape.path, np.array(shape.scale)))
    raise ParameterError(
        f"a {type(shape).__name__} is unbounded: it has no bounding spheres",
        name="shape",
        value=shape,
    )


def _prism(radius: float, length: float) -> HullPoints:
    """Return a prism circumscribing a cylinder about z."""
    n = _PRISM_SIDES
    outer = radius / math.cos(math.pi / n)
    angle = 2 * math.pi * np.arange(n) / n
    ring = np.column_stack([outer * np.cos(angle), outer * np.sin(angle)])
    points = np.vstack([np.column_stack([ring, np.full(n, z)]) for z in (-length / 2, length / 2)])
    return HullPoints(points=points, slack=outer - radius)


def _mesh_vertices(path: Path, scale: Array) -> Array:
    """Vertices [m] of a mesh file read by coal's loader (assimp, as Pinocchio)."""
    from youbot_opt.robot.urdf_check.geometry_cache import mesh_loader

    try:
        with mesh_loader([path]) as loader:
            bvh = loader.load(str(path), scale)
    except (RuntimeError, ValueError) as e:
        raise ModelError(f"cannot read the mesh {str(path)!r}: {e}", path=str(path)) from e
    return np.asarray(bvh.vertices(), dtype=float)


def geometry_hull(geometry: object) -> HullPoints:
    """Return a convex polytope containing a coal collision geometry (a link's).

    Parameters
    ----------
    geometry : coal.CollisionGeometry
        A Box, Sphere, Cylinder, Capsule or BVH mesh (``GeometryObject.geometry``;
        a mesh's vertices are already scaled).

    Returns
    -------
    HullPoints
        The polytope and its slack.

    Raises
    ------
    ModelError
        For another geometry type.
    """
    import coal

    if isinstance(geometry, coal.Box):
        return hull_points(Box(size=tuple(2 * float(h) for h in geometry.halfSide)))  # type: ignore[arg-type]
    if isinstance(geometry, coal.Sphere):
        return hull_points(Sphere(radius=float(geometry.radius)))
    if isinstance(geometry, coal.Cylinder):
        return _prism(float(geometry.radius), 2 * float(geometry.halfLength))
    if isinstance(geometry, coal.Capsule):
        return hull_points(
            Capsule(radius=float(geometry.radius), length=2 * float(geometry.halfLength))
        )
    if isinstance(geometry, coal.BVHModelBase):
        return HullPoints(points=np.asarray(geometry.vertices(), dtype=float))
    raise ModelError(
        f"collision geometry {type(geometry).__name__} has no bounding spheres "
        "(box, sphere, cylinder, capsule and meshes do)"
    )


def _directions(grid: int) -> tuple[Array, float]:
    """Return unit directions on a cube-sphere grid and their covering radius (chordal)."""
    t = np.linspace(-1.0, 1.0, grid + 1)
    grid_a, grid_b = np.meshgrid(t, t)
    a, b = grid_a.ravel(), grid_b.ravel()
    one = np.ones_like(a)
    faces = [
        np.column_stack(c)
        for c in ((one, a, b), (-one, a, b), (a, one, b), (a, -one, b), (a, b, one), (a, b, -one))
    ]
    stacked = np.vstack(faces)
    dirs: Array = stacked / np.linalg.norm(stacked, axis=1, keepdims=True)
    # a point of a face lies within sqrt(2)/GRID of a grid node; both at distance >= 1
    # from the origin, so their directions are within (pi/2) sqrt(2)/GRID (angle >= chord).
    return dirs, (math.pi / 2) * math.sqrt(2) / grid


def _hull(points: Array) -> tuple[Array, Array]:
    """Vertices and edges (pairs of indices into the vertices) of the convex hull."""
    from scipy.spatial import ConvexHull, QhullError  # SciPy: only when a hull is fitted

    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):  # flat or degenerate: every pair is a segment
        pts = np.unique(points, axis=0)
        idx = np.arange(len(pts))
        edges = np.array([(i, j) for i in idx for j in idx if i < j], dtype=int).reshape(-1, 2)
        return pts, edges
    vertices = hull.points[hull.vertices]
    remap = np.full(len(hull.points), -1, dtype=int)
    remap[hull.vertices] = np.arange(len(hull.vertices))
    tri = remap[hull.simplices]
    pairs = np.vstack([tri[:, [i, (i + 1) % tri.shape[1]]] for i in range(tri.shape[1])])
    return vertices, np.unique(np.sort(pairs, axis=1), axis=0)


def _slab_points(vertices: Array, edges: Array, coord: Array, lo: float, hi: float) -> Array:
    """Return the vertices of (hull ∩ lo <= coord <= hi): vertices inside and edge crossings."""
    inside = vertices[(coord >= lo) & (coord <= hi)]
    out = [inside]
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    ca, cb = coord[edges[:, 0]], coord[edges[:, 1]]
    for plane in (lo, hi):
        cross = (ca - plane) * (cb - plane) < 0
        if np.any(cross):
            s = ((plane - ca[cross]) / (cb[cross] - ca[cross]))[:, None]
            out.append(a[cross] + s * (b[cross] - a[cross]))
    return np.vstack(out)


def _centre(points: Array) -> Array:
    """Return a centre of a small ball around ``points``: Badoiu-Clarkson from the box centre.

    The radius is computed from the centre afterwards, so the ball contains
    the points whatever the centre; the iteration only makes it smaller.
    """
    box = (points.min(axis=0) + points.max(axis=0)) / 2
    centre = box.copy()
    for i in range(1, _CENTRE_ITERATIONS + 1):
        far = points[np.argmax(np.linalg.norm(points - centre, axis=1))]
        centre = centre + (far - centre) / (i + 1)
    reach = np.linalg.norm(points - centre, axis=1).max()
    return centre if reach < np.linalg.norm(points - box, axis=1).max() else box


def _clip(vertices: Array, edges: Array | None, lo: Array, hi: Array) -> Array:
    """Return points whose convex hull is (hull of ``vertices``) ∩ the box ``lo <= x <= hi``.

    One axis at a time: a convex polytope cut by a slab has for vertices its
    own vertices inside and its edges' crossings of the two planes.
    """
    part = vertices
    for axis in range(3):
        if len(part) == 0:
            break
        if edges is None or axis > 0:
            part, edges = _hull(part)
        part = _slab_points(part, edges, part[:, axis], float(lo[axis]), float(hi[axis]))
    return part


def _fit_cells(
    vertices: Array, counts: tuple[int, int, int], dirs: Array, cover: float
) -> SphereFit:
    """Fit one ball per cell of a ``counts`` grid over the principal-axes box; their overshoot."""
    centroid = vertices.mean(axis=0)
    _, _, vt = np.linalg.svd(vertices - centroid, full_matrices=False)
    axes = vt if vt.shape[0] == 3 else np.eye(3)
    local = (vertices - centroid) @ axes.T
    local, edges = _hull(local)
    cuts = [np.linspace(local[:, i].min(), local[:, i].max(), counts[i] + 1) for i in range(3)]
    centers, radii, overshoot = [], [], 0.0
    for i in range(counts[0]):
        for j in range(counts[1]):
            for k in range(counts[2]):
                lo = np.array([cuts[0][i], cuts[1][j], cuts[2][k]])
                hi = np.array([cuts[0][i + 1], cuts[1][j + 1], cuts[2][k + 1]])
                part = _clip(local, edges, lo, hi)
                if len(part) == 0:
                    continue
                center = _centre(part)
                radius = float(np.linalg.norm(part - center, axis=1).max())
                over = _overshoot(local, edges, part, (lo, hi), center, radius, dirs, cover)
                overshoot = max(overshoot, over)
                centers.append(center @ axes + centroid)
                radii.append(radius)
    return SphereFit(centers=np.array(centers), radii=np.array(radii), overshoot=overshoot)


def _grid_counts(extent: Array, max_spheres: int) -> list[tuple[int, int, int]]:
    """Cell counts to try, fewest cells first, at most ``max_spheres`` cells each.

    Slabs along the principal axis (1 to ``max_spheres``), and grids of
    cubic-ish cells whose edge ``s`` shrinks geometrically from the longest
    extent (an axis shorter than ``s`` is not cut), so that wide or L-shaped
    solids are cut across as well.
    """
    out: set[tuple[int, int, int]] = {(k, 1, 1) for k in range(1, max_spheres + 1)}
    longest = float(extent.max())
    for step in range(200) if longest > 0 else ():
        s = longest * 0.85**step
        counts = tuple(max(1, math.ceil(e / s - 1e-9)) for e in extent)
        if math.prod(counts) > max_spheres:
            break
        out.add(counts)  # type: ignore[arg-type]
    return sorted(out, key=lambda c: (math.prod(c), c))


def _overshoot(
    local: Array,
    edges: Array,
    part: Array,
    cell: tuple[Array, Array],
    center: Array,
    radius: float,
    dirs: Array,
    cover: float,
) -> float:
    """Upper bound [m] on the distance from a point of one ball to the hull.

    For a convex part ``P`` of the hull, ``sup_{p in ball} dist(p, P) = max_u
    (h_ball(u) - h_P(u))`` bounds the distance to the hull; sampled on the grid
    it misses at most ``(radius + max_P |x - center|) * cover`` (both support
    functions are Lipschitz). ``P`` is the hull's part within ``radius`` of the
    ball's cell (the cell's own part alone when that bound is smaller).
    """
    best = math.inf
    for grow in (0.0, radius):
        piece = part if grow == 0.0 else _clip(local, edges, cell[0] - grow, cell[1] + grow)
        piece = piece - center
        reach = float(np.linalg.norm(piece, axis=1).max())
        gap = float(np.max(radius - (dirs @ piece.T).max(axis=1)))
        best = min(best, max(gap, 0.0) + (radius + reach) * cover)
    return best


def _cache_key(hull: HullPoints, target: float, max_spheres: int) -> str:
    digest = hashlib.sha256()
    digest.update(np.ascontiguousarray(np.asarray(hull.points, dtype="<f8")).tobytes())
    digest.update(
        f"{_FIT_VERSION}|{_COARSE_GRID}|{_FINE_GRID}|{_CENTRE_ITERATIONS}|{_WORTH}|{hull.slack!r}|{target!r}|{max_spheres}".encode()
    )
    return digest.hexdigest()


def _read_cache(path: Path) -> SphereFit | None:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        fit = SphereFit(
            centers=np.array(doc["centers"], dtype=float).reshape(-1, 3),
            radii=np.array(doc["radii"], dtype=float),
            overshoot=float(doc["overshoot"]),
        )
    except (OSError, ValueError, KeyError, TypeError):
        return None
    ok = len(fit.radii) == len(fit.centers) > 0 and np.all(np.isfinite(fit.centers))
    return fit if ok and np.all(fit.radii > 0) else None


def fit_spheres(
    hull: HullPoints,
    *,
    target_overshoot: float = DEFAULT_TARGET_OVERSHOOT,
    max_spheres: int = DEFAULT_MAX_SPHERES,
    cache: bool = True,
) -> SphereFit:
    """Return balls whose union contains the polytope, with their overshoot bound.

    Parameters
    ----------
    hull : HullPoints
        The solid's containing polytope (:func:`hull_points`, :func:`geometry_hull`).
    target_overshoot : float
        The fit takes the grid with the fewest balls (1 to ``max_spheres``)
        whose overshoot is at most this, in [m]; when none is, the fewest
        balls within 2 mm of the best grid's overshoot.
    max_spheres : int
        Most balls.
    cache : bool
        Read and write the fit in :func:`collision_cache_dir`.

    Returns
    -------
    SphereFit
        Centres and radii in the solid's frame [m], overshoot [m] (the
        polytope's slack included).

    Raises
    ------
    ModelError
        The solid has more than 200,000 points or non-finite ones.
    """
    if hull.exact is not None:
        centers, radii = hull.exact
        return SphereFit(
            centers=centers,
            radii=radii,
            overshoot=hull.slack + float(radii.max() - radii.min())
            if len(radii) > 1
            else hull.slack,
        )
    points = np.asarray(hull.points, dtype=float)
    if len(points) > _MAX_POINTS or not np.all(np.isfinite(points)) or len(points) == 0:
        raise ModelError(
            f"a solid to fit needs 1 to {_MAX_POINTS} finite points, got {len(points)}"
        )
    path = collision_cache_dir() / f"spheres-{_cache_key(hull, target_overshoot, max_spheres)}.json"
    if cache and (hit := _read_cache(path)) is not None:
        return hit
    vertices, _ = _hull(points)
    centred = vertices - vertices.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axes = vt if vt.shape[0] == 3 else np.eye(3)
    local = centred @ axes.T
    extent = local.max(axis=0) - local.min(axis=0)
    # grids compared by the sampled overshoot on the coarse grid (no remainder: an
    # estimate, which would otherwise favour small balls); the chosen one is bounded below
    dirs, _ = _directions(_COARSE_GRID)
    tried: list[tuple[float, tuple[int, int, int]]] = []
    for counts in _grid_counts(extent, max_spheres):
        tried.append((_fit_cells(vertices, counts, dirs, 0.0).overshoot, counts))
        if tried[-1][0] + hull.slack <= target_overshoot:
            break
    # the fewest balls within _WORTH of the best bound: more balls cost the NLP more
    # than a few millimetres of overshoot are worth
    best_over = min(over for over, _ in tried)
    chosen = next(
        t for t in tried if t[0] <= max(best_over + _WORTH, target_overshoot - hull.slack)
    )
    # the chosen grid again, its overshoot bounded on the fine grid (a smaller remainder)
    best = _fit_cells(vertices, chosen[1], *_directions(_FINE_GRID))
    result = SphereFit(
        centers=best.centers, radii=best.radii, overshoot=best.overshoot + hull.slack
    )
    if cache:
        doc = {
            "centers": result.centers.tolist(),
            "radii": result.radii.tolist(),
            "overshoot": result.overshoot,
        }
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(path, json.dumps(doc))
        except OSError as e:  # a read-only cache costs time only
            _log.warning("cannot cache a sphere fit in %s: %s", path, e)
    return result
