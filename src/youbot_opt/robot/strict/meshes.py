"""Which mesh and texture files a meshcat scene may embed.

A scene sent to meshcat, and above all an exported HTML file that will be
passed around, carries the bytes of every mesh and texture it shows. Those
bytes may only come from the robot's own package directories
(``robot.package_dirs``), so that a robot description cannot smuggle other
files of the machine into a page. The rules:

1. A mesh file is named by a plain local path (no ``scheme://``). Following
   every symlink, it must resolve to a regular file inside one of the package
   directories, and have one of the suffixes :data:`MESH_SUFFIXES`.
2. A COLLADA (``.dae``) mesh names its textures in the ``<init_from>`` of its
   ``<library_images>``. Each must be a relative path (after percent- and
   XML-decoding) that, from the ``.dae`` file's folder and following symlinks,
   resolves to a regular file inside a package directory. Absolute paths and
   URLs (``file://``, ``http://``, ...) are refused; ``data:image/...`` URIs,
   which name no file, are kept as they are.
3. Wavefront (``.obj``) and STL meshes are embedded as their own bytes only;
   the viewer never follows an ``.obj`` file's ``mtllib``.

Every refusal is a :class:`~youbot_opt.exceptions.ModelError` whose message
names the file and the rule it breaks, and, when the caller passes
``referenced_by`` (e.g. the robot and geometry object), what referenced the
mesh; a texture's refusal names the ``.dae`` file and the texture. Nothing is
embedded before the checks pass. A file swapped between the check and the read by someone with write
access to the package directories is out of scope.
"""

from __future__ import annotations

import base64
import logging
import mimetypes
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import NamedTuple
from urllib.parse import unquote

from youbot_opt.exceptions import ModelError

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

#: Mesh formats the meshcat viewer can parse, by lower-case suffix.
MESH_SUFFIXES: tuple[str, ...] = (".dae", ".stl", ".obj")
#: Texture image formats a browser decodes, by lower-case suffix.
TEXTURE_SUFFIXES: tuple[str, ...] = (".png", ".jpg", ".jpeg", ".gif", ".bmp", ".webp")

_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")
_WINDOWS_DRIVE = re.compile(r"^[A-Za-z]:[\\/]")


class TextureReference(NamedTuple):
    """One texture named by a COLLADA file.

    Attributes
    ----------
    key : str
        The ``<init_from>`` text exactly as the browser's COLLADA loader reads
        it (XML-decoded, whitespace kept): the key of the resource map.
    target : str
        The same text stripped and percent-decoded: what it points to.
    """

    key: str
    target: str


@dataclass(frozen=True, slots=True, kw_only=True)
class MeshFile:
    """A mesh file that passed the policy, with the bytes to embed.

    Attributes
    ----------
    path : Path
        The mesh file, symlinks resolved.
    format : str
        ``"dae"``, ``"stl"`` or ``"obj"``.
    data : bytes
        The file's content.
    resources : Mapping of str to str
        For COLLADA files, texture ``<init_from>`` text to ``data:`` URI (read
        only); empty otherwise.
    """

    path: Path
    format: str
    data: bytes
    resources: Mapping[str, str]


def _roots(package_dirs: Sequence[str | Path]) -> tuple[Path, ...]:
    roots = tuple(Path(d).resolve() for d in package_dirs)
    return tuple(r for r in roots if r.is_dir())


def _inside(path: Path, roots: Sequence[Path]) -> bool:
    return any(path.is_relative_to(root) for root in roots)


def _refuse(file: str | Path, rule: str, detail: str, referenced_by: str = "") -> ModelError:
    prefix = f"{referenced_by}: " if referenced_by else ""
    return ModelError(
        f"{prefix}refusing to embed {str(file)!r}: {detail} (rule: {rule})", path=str(file)
    )


def _check_inside(
    named: str | Path,
    candidate: Path,
    roots: Sequence[Path],
    what: str,
    suffixes: Sequence[str],
    referenced_by: str,
) -> Path:
    """Resolve ``candidate`` (following symlinks) and check rules 1/2 for it."""
    if not roots:
        raise _refuse(
            named,
            f"{what}s must lie inside the robot's package directories",
            "the robot declares no existing package directory",
            referenced_by,
        )
    try:
        resolved = candidate.resolve(strict=True)
    except (OSError, RuntimeError) as e:
        raise _refuse(
            named,
            f"{what}s are existing files",
            f"it does not exist or cannot be resolved: {e}",
            referenced_by,
        ) from e
    if not _inside(resolved, roots):
        raise _refuse(
            named,
            f"{what}s must lie inside the robot's package directories "
            f"{', '.join(str(r) for r in roots)}",
            f"it resolves to {str(resolved)!r}",
            referenced_by,
        )
    if not resolved.is_file():
        raise _refuse(
            named, f"{what}s must be regular files", f"{str(resolved)!r} is not one", referenced_by
        )
    if resolved.suffix.lower() not in suffixes:
        raise _refuse(
            named,
            f"{what}s must have one of the suffixes {', '.join(suffixes)}",
            f"its suffix is {resolved.suffix!r}",
            referenced_by,
        )
    return resolved


def check_mesh_file(
    mesh_path: str | Path, package_dirs: Sequence[str | Path], *, referenced_by: str = ""
) -> Path:
    """Check a mesh file against rule 1 and return its resolved path.

    Parameters
    ----------
    mesh_path : str or Path
        The mesh file as the geometry object names it (``GeometryObject.meshPath``).
    package_dirs : sequence of str or Path
        The robot's package directories.
    referenced_by : str
        What references the mesh, put first in error messages, e.g.
        ``"robot 'ur5', visual geometry 'wrist_1_link_0'"``; empty to omit.

    Returns
    -------
    Path
        The mesh file with every symlink resolved.

    Raises
    ------
    ModelError
        If the path is a URL, escapes the package directories, is not a
        regular file, does not exist or has an unsupported suffix.
    """
    text = str(mesh_path)
    if _SCHEME.match(text) and not _WINDOWS_DRIVE.match(text):
        raise _refuse(text, "meshes are named by local file paths", "it is a URL", referenced_by)
    roots = _roots(package_dirs)
    return _check_inside(text, Path(text), roots, "mesh", MESH_SUFFIXES, referenced_by)


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
        One entry per ``<image>``'s ``<init_from>`` (COLLADA 1.4 text or 1.5
        ``<ref>``), in document order.

    Raises
    ------
    ModelError
        If the document is not well-formed XML.
    """
    try:
        root = ET.fromstring(dae_bytes)
    except ET.ParseError as e:
        raise _refuse(path, "COLLADA files are well-formed XML", f"not well-formed XML: {e}") from e
    refs: list[TextureReference] = []
    for library in root.iter():
        if _local(library.tag) != "library_images":
            continue
        for element in library.iter():
            if _local(element.tag) == "init_from":
                key = "".join(element.itertext())
                refs.append(TextureReference(key=key, target=unquote(key.strip())))
    return refs


def _local(tag: object) -> str:
    return str(tag).rsplit("}", 1)[-1]


def _texture_uri(
    dae_path: Path, ref: TextureReference, roots: Sequence[Path], referenced_by: str
) -> str:
    """Check one texture reference against rule 2 and return its ``data:`` URI.

    ``dae_path`` is the COLLADA file as named (before resolving symlinks): its
    textures are relative to that folder, as for assimp and Pinocchio.
    """
    target = ref.target
    if target.lower().startswith("data:image/"):
        return ref.key
    named = f"{dae_path} -> {target}"
    rule = "textures are named by relative paths"
    if _SCHEME.match(target) and not _WINDOWS_DRIVE.match(target):
        raise _refuse(named, rule, "it is a URL", referenced_by)
    if target.startswith(("/", "\\")) or _WINDOWS_DRIVE.match(target):
        raise _refuse(named, rule, "it is an absolute path", referenced_by)
    resolved = _check_inside(
        named, dae_path.parent / target, roots, "texture", TEXTURE_SUFFIXES, referenced_by
    )
    mime = mimetypes.guess_type(resolved.name)[0] or "application/octet-stream"
    return f"data:{mime};base64,{base64.b64encode(resolved.read_bytes()).decode('ascii')}"


def load_mesh_file(
    mesh_path: str | Path, package_dirs: Sequence[str | Path], *, referenced_by: str = ""
) -> MeshFile:
    """Check a mesh file (and a COLLADA file's textures) and read what to embed.

    Parameters
    ----------
    mesh_path : str or Path
        The mesh file as the geometry object names it.
    package_dirs : sequence of str or Path
        The robot's package directories.
    referenced_by : str
        What references the mesh, put first in error messages, e.g.
        ``"robot 'ur5', visual geometry 'wrist_1_link_0'"``; empty to omit.

    Returns
    -------
    MeshFile
        The mesh bytes, and for COLLADA files the textures as ``data:`` URIs.

    Raises
    ------
    ModelError
        If the mesh or one of its textures breaks a rule of this module.
    """
    resolved = check_mesh_file(mesh_path, package_dirs, referenced_by=referenced_by)
    data = resolved.read_bytes()
    fmt = resolved.suffix.lower().lstrip(".")
    resources: dict[str, str] = {}
    if fmt == "dae":
        roots = _roots(package_dirs)
        try:
            references = dae_texture_references(data, path=resolved)
        except ModelError as e:
            if not referenced_by:
                raise
            raise ModelError(f"{referenced_by}: {e}", path=e.path) from e
        for ref in references:
            resources[ref.key] = _texture_uri(Path(mesh_path), ref, roots, referenced_by)
    logger.debug("mesh %s passed the policy (%d textures)", resolved, len(resources))
    return MeshFile(path=resolved, format=fmt, data=data, resources=MappingProxyType(resources))
