"""What the meshcat replay embeds of a mesh file: its bytes, its textures, a PLY as STL.

Every path decision is :mod:`youbot_opt.robot.urdf_check.resources`'s, so the replay
accepts exactly the meshes the strict loader accepts. :func:`load_mesh_file`
adds what embedding needs: the bytes, each COLLADA texture as a ``data:`` URI
and ``.ply`` meshes (which meshcat cannot parse) as binary STL. Errors are the
loader's URDFError subclasses.

>>> mesh = load_mesh_file(path, robot.package_dirs, referenced_by="link 'arm_0'")  # doctest: +SKIP
"""

from __future__ import annotations

import base64
import logging
import mimetypes
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import NamedTuple
from urllib.parse import unquote

import numpy as np
from lxml import etree

from youbot_opt.exceptions import InvalidModelError, UnsafePathError, URDFError
from youbot_opt.robot.urdf_check.geometry_cache import mesh_loader
from youbot_opt.robot.urdf_check.resources import (
    MAX_RESOURCE_BYTES,
    MESH_SUFFIXES,
    PATH_RULE,
    allowed_roots,
    check_mesh,
    in_mesh,
    is_inline_image,
    read_regular_file,
    resolve_in_folder,
    resolve_reference,
)
from youbot_opt.robot.urdf_check.xml import Site, fail, local_name, parse_xml_strict

__all__ = [
    "MESH_SUFFIXES",
    "TEXTURE_SUFFIXES",
    "MeshFile",
    "TextureReference",
    "check_mesh_file",
    "dae_texture_references",
    "load_mesh_file",
]

logger = logging.getLogger(__name__)

#: Texture image formats a browser decodes, by lower-case suffix.
TEXTURE_SUFFIXES: tuple[str, ...] = (".png", ".jpg", ".jpeg", ".gif", ".bmp", ".webp")
#: Mesh formats meshcat's viewer parses itself; the others are converted to STL.
_VIEWER_FORMATS: tuple[str, ...] = (".dae", ".stl", ".obj")
_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])


class TextureReference(NamedTuple):
    """One texture named by a COLLADA file.

    Attributes
    ----------
    key : str
        The ``<init_from>`` text exactly as the browser's COLLADA loader reads
        it (XML-decoded, whitespace kept): the key of the resource map.
    target : str
        The same text stripped and percent-decoded: what it points to.
    line : int or None
        1-based line of the ``<init_from>`` in the COLLADA file.
    """

    key: str
    target: str
    line: int | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class MeshFile:
    """A mesh file that passed the policy, with the bytes to embed.

    Attributes
    ----------
    path : Path
        The mesh file, symlinks resolved.
    format : str
        Format of ``data``: ``"dae"``, ``"stl"`` or ``"obj"`` (a ``.ply`` file
        is converted to binary STL).
    data : bytes
        The content to embed.
    resources : Mapping of str to str
        For COLLADA files, texture ``<init_from>`` text to ``data:`` URI (read
        only); empty otherwise.
    """

    path: Path
    format: str
    data: bytes
    resources: Mapping[str, str]


def dae_texture_references(
    dae_bytes: bytes, *, path: str | Path = "<dae>"
) -> list[TextureReference]:
    """List the texture files a COLLADA document names in ``<library_images>``.

    Parameters
    ----------
    dae_bytes : bytes
        The COLLADA document.
    path : str or Path
        Its file name, for error messages.

    Returns
    -------
    list of TextureReference
        One entry per ``<init_from>`` (COLLADA 1.4 text or 1.5 ``<ref>``), in
        document order.

    Raises
    ------
    URDFSyntaxError, UnsafeURDFError
        If the document is not well-formed XML, or declares a DOCTYPE or entities.
    """
    tree = parse_xml_strict(dae_bytes, os.fspath(path), long_text=True)
    found: list[TextureReference] = []
    collected: set[etree._Element] = set()
    for elem in tree.getroot().iter():  # document order
        if local_name(elem.tag) != "init_from":
            continue
        ancestors = list(elem.iterancestors())
        if any(a in collected for a in ancestors):
            continue  # its text is part of the enclosing <init_from>'s
        if any(local_name(a.tag) == "library_images" for a in ancestors):
            collected.add(elem)
            key = "".join(elem.itertext())
            found.append(TextureReference(key, unquote(key.strip()), elem.sourceline))
    return found


def _checked(
    mesh_path: str | Path, package_dirs: Sequence[str | Path], referenced_by: str
) -> tuple[Path, tuple[Path, ...], Site]:
    """Apply the resource policy to a mesh file: its real path, the roots and its site."""
    roots = allowed_roots(package_dirs, skip_missing=True)
    where = Site(os.fspath(mesh_path), referenced_by or "mesh", None)
    if not roots:
        problem = "the robot declares no existing package directory"
        raise fail(UnsafePathError, where, problem, PATH_RULE)
    real = resolve_reference(os.fspath(mesh_path), roots, roots, where)
    try:
        check_mesh(real, roots, where, inline_images=True, material_warning=False)
    except URDFError as e:
        if (e.path, e.element, e.line) == where:  # about the mesh file itself
            raise
        raise in_mesh(e, where, real) from e
    return real, roots, where


def check_mesh_file(
    mesh_path: str | Path, package_dirs: Sequence[str | Path], *, referenced_by: str = ""
) -> Path:
    """Check a mesh file (and what it references) against the resource policy.

    Parameters
    ----------
    mesh_path : str or Path
        The mesh file as the geometry object names it (``GeometryObject.meshPath``).
    package_dirs : sequence of str or Path
        The robot's package directories (folders that do not exist are left out).
    referenced_by : str
        What references the mesh, e.g. ``"geometry object 'wrist_1_link_0'"``;
        it names the element in error messages (``"mesh"`` when empty).

    Returns
    -------
    Path
        The mesh file with every symlink resolved.

    Raises
    ------
    UnsafePathError
        If the path is a refused URL form, escapes the package directories,
        is not a regular file, is too large or has a format not in
        :data:`MESH_SUFFIXES`, or a texture or material library it names escapes.
    ResourceNotFoundError
        If the mesh or one of its COLLADA textures does not exist.
    URDFSyntaxError, UnsafeURDFError
        If a COLLADA file is not well-formed XML or declares a DOCTYPE.
    """
    return _checked(mesh_path, package_dirs, referenced_by)[0]


def _texture_uri(dae: Path, ref: TextureReference, roots: Sequence[Path], where: Site) -> str:
    """Return the ``data:`` URI that replaces one COLLADA texture reference."""
    if is_inline_image(ref.key):
        return ref.key
    at = Site(os.fspath(dae), "<init_from>", ref.line)
    try:
        real = resolve_in_folder(ref.key.strip(), roots, dae.parent, at)[0]
        if real.suffix.lower() not in TEXTURE_SUFFIXES:
            problem = f"texture {ref.key.strip()!r} has the format {real.suffix or '(none)'!r}"
            rule = f"embedded textures are {', '.join(TEXTURE_SUFFIXES)} (browsers decode them)"
            raise fail(UnsafePathError, at, problem, rule)
        data = read_regular_file(real, MAX_RESOURCE_BYTES, at, "texture")
    except URDFError as e:
        raise in_mesh(e, where, dae) from e
    mime = mimetypes.guess_type(real.name)[0] or "application/octet-stream"
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def _ply_as_stl(real: Path, where: Site) -> bytes:
    """Binary STL of the triangles coal (assimp) reads from a PLY file, unscaled."""
    try:
        with mesh_loader([real]) as loader:
            bvh = loader.load(os.fspath(real), np.ones(3))
    except (RuntimeError, ValueError) as e:
        problem = f"mesh {os.fspath(real)!r} is not a PLY file assimp reads: {e}"
        raise fail(InvalidModelError, where, problem, "meshes are readable by assimp") from e
    vertices = np.asarray(bvh.vertices(), dtype=float).reshape(-1, 3)
    faces = [[t[0], t[1], t[2]] for t in map(bvh.tri_indices, range(bvh.num_tris))]
    corners = vertices[np.asarray(faces, dtype=np.int64).reshape(-1, 3)]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    records = np.zeros(len(corners), dtype=_STL_RECORD)
    records["normal"] = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    records["vertices"] = corners
    # a binary STL header must not start with "solid" (readers take it for ASCII)
    header = f"binary STL of {real.name}".encode()[:80].ljust(80, b" ")
    return header + np.uint32(len(records)).tobytes() + records.tobytes()


def load_mesh_file(
    mesh_path: str | Path, package_dirs: Sequence[str | Path], *, referenced_by: str = ""
) -> MeshFile:
    """Check a mesh file (and a COLLADA file's textures) and read what to embed.

    The mesh resolves like a URDF reference to a regular file inside the
    package directories, with a format of
    :data:`~youbot_opt.robot.urdf_check.resources.MESH_SUFFIXES`, and a COLLADA
    file's textures resolve from its folder by the same rules. Each texture
    becomes a ``data:`` URI keyed by the ``<init_from>`` text the browser reads
    (inline ``data:image/`` URIs are kept; textures in :data:`TEXTURE_SUFFIXES`),
    and a ``.ply`` mesh becomes binary STL of the triangles coal (assimp, as in
    Pinocchio) reads.

    Parameters
    ----------
    mesh_path : str or Path
        The mesh file as the geometry object names it.
    package_dirs : sequence of str or Path
        The robot's package directories.
    referenced_by : str
        What references the mesh, e.g. ``"geometry object 'wrist_1_link_0'"``.

    Returns
    -------
    MeshFile
        The mesh bytes (a ``.ply`` file as binary STL), and for COLLADA files
        the textures as ``data:`` URIs.

    Raises
    ------
    URDFError
        As :func:`check_mesh_file`; also :class:`~youbot_opt.exceptions.UnsafePathError`
        for a texture browsers do not decode, and
        :class:`~youbot_opt.exceptions.InvalidModelError` for a PLY file assimp
        cannot read.
    """
    real, roots, where = _checked(mesh_path, package_dirs, referenced_by)
    suffix = real.suffix.lower()
    if suffix not in _VIEWER_FORMATS:  # .ply: meshcat's viewer has no parser for it
        data, fmt = _ply_as_stl(real, where), "stl"
    else:
        data, fmt = read_regular_file(real, MAX_RESOURCE_BYTES, where, "mesh"), suffix[1:]
    resources: dict[str, str] = {}
    if fmt == "dae":
        for ref in dae_texture_references(data, path=real):
            resources[ref.key] = _texture_uri(real, ref, roots, where)
    logger.debug("mesh %s passed the policy (%d textures)", real, len(resources))
    return MeshFile(path=real, format=fmt, data=data, resources=MappingProxyType(resources))
