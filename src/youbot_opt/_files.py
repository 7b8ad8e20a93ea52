"""The files youbot_opt writes: atomic writes, JSON sanitising, JSON Lines, the schema header.

Owns what every writer of a result, record, manifest or summary needs, written
once: :func:`atomic_write_bytes` (a kill leaves the old file or the new one),
:func:`json_ready` (numpy values, paths, enums to JSON, NaN/inf to ``null``),
:func:`write_json_lines` (one JSON object a line: a sweep's per-start rows),
:func:`read_npz` / :func:`read_regular_file` (bounded reads that never block) and
:func:`schema_header` / :func:`check_schema_header` (schema name, version,
writing software, checksum). Layer 0. Example::

    doc = {**schema_header("youbot_opt.x", 1, sha256=json_digest(body)), "result": body}
    atomic_write_text(path, json.dumps(json_ready(doc), allow_nan=False))
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import stat
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from types import ModuleType
from typing import IO, Any

import numpy as np

from youbot_opt.exceptions import ParameterError, ResultFileError

__all__ = [
    "MAX_RESULT_BYTES",
    "MIGRATION_SCRIPT",
    "TMP_PREFIX",
    "array_digest",
    "atomic_write_bytes",
    "atomic_write_text",
    "atomic_writer",
    "check_schema_header",
    "file_kind",
    "fsync_dir",
    "json_digest",
    "json_ready",
    "json_roundtrip",
    "read_json_lines",
    "read_npz",
    "read_input_text",
    "read_regular_file",
    "schema_header",
    "software_versions",
    "write_json_lines",
]

MIGRATION_SCRIPT = "scripts/migrate_0_1_0.py"
"""The script that carries files and stores written by youbot_opt 0.1.0 forward."""

TMP_PREFIX = ".tmp-"
_MAX_REASON = 300  # characters of a library's own reason quoted in an error (zipfile quotes bytes)
"""Name prefix of the temporary files of :func:`atomic_writer` (``.tmp-<name>.<random>``)."""


# ---------------------------------------------------------------- atomic writes
def fsync_dir(directory: str | os.PathLike[str]) -> None:
    """Make a rename inside ``directory`` durable (no-op where folders cannot be opened).

    Parameters
    ----------
    directory : path-like
        The folder whose entry list is flushed to disk.
    """
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def file_kind(mode: int) -> str:
    """Name what a file that is not a regular file is, for a message (``"a FIFO"``).

    Parameters
    ----------
    mode : int
        ``st_mode`` of :func:`os.stat` or :func:`os.lstat`.

    Returns
    -------
    str
        ``"a FIFO"``, ``"a character device"``, ``"a block device"``, ``"a socket"``,
        ``"a folder"``, ``"a symbolic link"`` or ``"a regular file"``.
    """
    kinds = (
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISLNK, "a symbolic link"),
        (stat.S_ISREG, "a regular file"),
    )
    return next((name for test, name in kinds if test(mode)), "not a regular file")


def _process_umask() -> int:
    """Return the process umask, read without changing it where the system allows."""
    with contextlib.suppress(OSError, ValueError):
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)  # no /proc: read it by setting it, and put it back at once
    os.umask(mask)
    return mask


def _mode_for(target: Path) -> int:
    """Return the permission bits for a new ``target``; refuse a link or a non-regular file."""
    try:
        info = os.lstat(target)
    except FileNotFoundError:
        return 0o666 & ~_process_umask()
    if stat.S_ISLNK(info.st_mode):
        raise ParameterError(
            f"refusing to write {str(target)!r}: it is a symbolic link (to "
            f"{os.readlink(target)!r}); remove it or choose another output path"
        )
    if not stat.S_ISREG(info.st_mode):
        kind = file_kind(info.st_mode)
        kind = kind if kind == "a folder" else f"not a regular file but {kind}"
        raise ParameterError(
            f"refusing to write {str(target)!r}: it is {kind} (a device, FIFO, socket "
            "or folder is never replaced); choose a regular file's path"
        )
    return stat.S_IMODE(info.st_mode)


@contextlib.contextmanager
def atomic_writer(path: str | os.PathLike[str]) -> Iterator[IO[bytes]]:
    """Open a binary handle whose content replaces ``path`` atomically on success.

    The handle writes to ``.tmp-<name>.<random>`` in the target's folder; on a
    clean exit it is flushed, ``fsync``-ed, renamed over ``path`` with
    :func:`os.replace` and the folder is ``fsync``-ed. On any exception
    (including ``KeyboardInterrupt``) the temporary file is removed and the
    exception propagates; ``path`` is left untouched.

    The new file gets the mode a plain ``open(path, "w")`` would give it (``0o666``
    less the process umask), or the mode of the regular file it replaces. A
    destination that is a symbolic link or not a regular file (a device, a FIFO, a
    folder) is refused before anything is written: a replace would put a file where
    the link or the device node was.

    Parameters
    ----------
    path : path-like
        Destination file; its folder must exist.

    Raises
    ------
    ParameterError
        ``path`` is a symbolic link or exists and is not a regular file.

    Yields
    ------
    IO[bytes]
        The handle to write the full new content to.
    """
    target = Path(path)
    mode = _mode_for(target)
    try:
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f"{TMP_PREFIX}{target.name}.")
    except OSError as exc:  # no folder, a read-only one, a full disk: name the file meant
        if exc.errno is not None:
            exc.filename = str(target)
        raise
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.errno is not None and exc.filename in (None, tmp):
            exc.filename = str(target)
        raise
    fsync_dir(target.parent)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temporary file, fsync, :func:`os.replace`).

    Parameters
    ----------
    path : path-like
        Destination file; its folder must exist.
    data : bytes
        Full new content.
    """
    with atomic_writer(path) as handle:
        handle.write(data)


def atomic_write_text(path: str | os.PathLike[str], text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically, encoded with ``encoding`` (UTF-8 by default).

    Parameters
    ----------
    path : path-like
        Destination file; its folder must exist.
    text : str
        Full new content.
    encoding : str
        Text encoding.
    """
    atomic_write_bytes(path, text.encode(encoding))


# ---------------------------------------------------------------- JSON
def json_ready(value: Any) -> Any:
    """``value`` as strict JSON: numpy values, paths and enums converted, NaN/inf as ``None``.

    Mappings become dicts with ``str`` keys, tuples and arrays lists, numpy
    scalars Python scalars, :class:`~pathlib.Path` a string, a non-``str``/``int``
    enum its ``value``, and non-finite floats ``None`` (JSON has no NaN). Other
    values are returned unchanged.

    Parameters
    ----------
    value : Any
        A nest of mappings, sequences and scalars.

    Returns
    -------
    Any
        The converted nest; ``json.dumps(..., allow_nan=False)`` accepts it
        when every leaf is a JSON scalar.
    """
    if isinstance(value, Mapping):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return [json_ready(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return json_ready(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "value") and hasattr(value, "name") and not isinstance(value, (int, str)):
        return json_ready(value.value)  # enums
    return value


def write_json_lines(path: str | os.PathLike[str], rows: Iterable[Mapping[str, object]]) -> int:
    """Write ``rows`` to ``path`` as JSON Lines (one JSON object a line), atomically.

    Each row goes through :func:`json_ready` and is written as it comes, so
    the rows of a long sweep never sit in memory together.

    Parameters
    ----------
    path : str or os.PathLike
        The file, conventionally ``*.jsonl``; replaced as :func:`atomic_writer` does.
    rows : iterable of mapping
        The objects, in order.

    Returns
    -------
    int
        The number of rows written.
    """
    count = 0
    with atomic_writer(path) as handle:
        for row in rows:
            line = json.dumps(json_ready(row), allow_nan=False, separators=(",", ":"))
            handle.write(line.encode("utf-8") + b"\n")
            count += 1
    return count


def read_json_lines(path: str | os.PathLike[str]) -> Iterator[dict[str, object]]:
    """Yield the objects of a JSON Lines file in order (blank lines are skipped).

    Raises
    ------
    ResultFileError
        If a line is not a JSON object.
    """
    with open(path, encoding="utf-8") as handle:
        for number, line in enumerate(handle, start=1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError as exc:
                raise ResultFileError(f"{path}:{number}: not JSON ({exc})") from exc
            if not isinstance(row, dict):
                raise ResultFileError(f"{path}:{number}: not a JSON object")
            yield row


def json_roundtrip(value: Any) -> Any:
    """``value`` exactly as it reads back from JSON, non-finite floats kept as NaN/inf.

    Unlike :func:`json_ready` this neither maps NaN/inf to ``None`` nor converts
    numpy values (they raise ``TypeError``): it is for comparing parameters with
    the ones a file holds (tuples become lists, floats stay bit-exact).

    Parameters
    ----------
    value : Any
        Plain JSON-serialisable data.

    Returns
    -------
    Any
        ``json.loads(json.dumps(value, allow_nan=True))``.
    """
    return json.loads(json.dumps(value, allow_nan=True))


# ---------------------------------------------------------------- schema header
def software_versions(*modules: ModuleType) -> dict[str, str]:
    """Versions of youbot_opt and of ``modules``, keyed by package name.

    Parameters
    ----------
    *modules : module
        Imported packages with a ``__version__`` (``pinocchio``, ``numpy``, ...).

    Returns
    -------
    dict
        ``{"youbot_opt": ..., "<module name>": ..., ...}`` in argument order.
    """
    from youbot_opt._version import __version__

    versions = {"youbot_opt": str(__version__)}
    for module in modules:
        versions[module.__name__] = str(module.__version__)  # type: ignore[attr-defined]
    return versions


def array_digest(arr: Any) -> str:
    """SHA-256 hex digest of an array's C-contiguous bytes (dtype and shape not included)."""
    return hashlib.sha256(np.ascontiguousarray(arr).tobytes()).hexdigest()


def json_digest(body: Any) -> str:
    """SHA-256 hex digest of the canonical JSON of ``body`` (sorted keys, no spaces, no NaN).

    Raises
    ------
    ValueError
        If ``body`` holds a non-finite float.
    """
    canonical = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def schema_header(
    schema: str, version: int, versions: Mapping[str, str] | None = None, **checksums: Any
) -> dict[str, Any]:
    """Return the leading fields of a file we write: schema, version, writer versions, checksums.

    Parameters
    ----------
    schema : str
        Schema name, e.g. ``"youbot_opt.ikpath_result"``.
    version : int
        Schema version (>= 1).
    versions : mapping, optional
        Software versions (:func:`software_versions`); youbot_opt's alone when omitted.
    **checksums
        Checksum fields in the order given, e.g. ``sha256=json_digest(body)``.

    Returns
    -------
    dict
        ``{"schema", "schema_version", "versions", **checksums}`` in that order.
    """
    return {
        "schema": schema,
        "schema_version": int(version),
        "versions": dict(software_versions() if versions is None else versions),
        **checksums,
    }


def check_schema_header(
    doc: Any,
    *,
    schema: str | None,
    supported: int,
    source: str,
    remedy: str = "upgrade youbot_opt to read it",
    oldest: int = 1,
    migrate: str | None = None,
) -> int:
    """Check the schema name and version of a file read back; return the version.

    Parameters
    ----------
    doc : Any
        The parsed document (a dict with ``schema`` and ``schema_version``).
    schema : str or None
        Expected schema name; ``None`` skips the name check.
    supported : int
        Newest schema version this code reads (1..``supported`` are accepted).
    source : str
        What was read, for the messages (e.g. the path).
    remedy : str
        What the user can do about a file of a newer version (end of that message).
    oldest : int
        Oldest schema version this code reads. An older file was written by
        youbot_opt 0.1.0: the message names the script that carries it forward
        (:data:`MIGRATION_SCRIPT`; until 1.0 the package reads one format).
    migrate : str, optional
        The path to give that script (default ``source``; a store's folder).

    Returns
    -------
    int
        The file's schema version.

    Raises
    ------
    ResultFileError
        If the schema is another one, or the version is not an integer, < 1 or
        newer than ``supported`` (the message names the youbot_opt that wrote it),
        or older than ``oldest`` (the message names the migration script).
    """
    if schema is not None and (not isinstance(doc, dict) or doc.get("schema") != schema):
        found = doc.get("schema") if isinstance(doc, dict) else type(doc).__name__
        raise ResultFileError(f"{source}: unknown schema {found!r}, expected {schema!r}")
    if not isinstance(doc, dict):
        raise ResultFileError(f"{source} is corrupted: a {type(doc).__name__}, not a JSON object")
    version = doc.get("schema_version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ResultFileError(
            f"{source} is corrupted: no valid 'schema_version' field (expected an integer "
            f"in 1..{supported}, got {version!r})"
        )
    if version < oldest:
        raise ResultFileError(
            f"{source}: written by youbot_opt 0.1.0 (schema {version}); run "
            f"`python {MIGRATION_SCRIPT} {source if migrate is None else migrate}` to carry "
            "it forward"
        )
    if version > supported:
        versions = doc.get("versions")
        writer = versions.get("youbot_opt") if isinstance(versions, dict) else None
        written_by = f"; the file was written by youbot_opt {writer}" if writer else ""
        raise ResultFileError(
            f"{source}: schema version {version} is newer than this youbot_opt reads "
            f"(versions 1..{supported}){written_by}; {remedy}"
        )
    return version


MAX_RESULT_BYTES = 256 * 2**20
"""Largest uncompressed content [bytes] of a result file we read (256 MiB).

A 1000-knot, 7-joint Radau plan with every saved array is about 2 MB; the
limit only stops a file that declares more (a zip bomb, an ``.npy`` header
declaring 10^11 floats) before its memory is asked for.
"""


def read_npz(path: Path, *, max_bytes: int = MAX_RESULT_BYTES) -> dict[str, np.ndarray]:
    """Read every array of an ``.npz`` file, refusing what declares more than it may hold.

    Each member's ``.npy`` header is read first: a member whose declared shape
    needs more bytes than the member holds, or a file whose uncompressed
    members add up to more than ``max_bytes``, is refused before any array is
    allocated. Nothing is unpickled.

    Parameters
    ----------
    path : Path
        The ``.npz`` file.
    max_bytes : int, optional
        Largest total uncompressed size [bytes] (:data:`MAX_RESULT_BYTES`).

    Returns
    -------
    dict of str to ndarray
        The arrays by member name (without ``.npy``).

    Raises
    ------
    ResultFileError
        If the file is not a readable ``.npz`` (the message says why), holds
        more than ``max_bytes`` or declares arrays larger than its content.
    """
    import zipfile
    import zlib

    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
            total = sum(info.file_size for info in infos)
            if total > max_bytes:
                raise ResultFileError(
                    f"{path} holds {total} bytes uncompressed, more than the limit "
                    f"MAX_RESULT_BYTES = {max_bytes} of a result file; not read"
                )
            for info in infos:
                with archive.open(info) as member:
                    version = np.lib.format.read_magic(member)
                    read_header = (
                        np.lib.format.read_array_header_1_0
                        if version == (1, 0)
                        else np.lib.format.read_array_header_2_0
                    )
                    shape, _, dtype = read_header(member)
                    declared = math.prod(shape) * dtype.itemsize
                    if dtype.hasobject or declared > info.file_size:
                        raise ResultFileError(
                            f"{path}: member {info.filename!r} declares an array of shape "
                            f"{shape} ({declared} bytes of {dtype}) but holds "
                            f"{info.file_size} bytes; corrupted or forged, not read"
                        )
        with np.load(path, allow_pickle=False) as npz:
            return {key: np.array(npz[key]) for key in npz.files}
    except ResultFileError:
        raise
    except (  # what zipfile and zlib raise on forged archives (encrypted: RuntimeError)
        OSError, ValueError, zipfile.BadZipFile, EOFError, KeyError, zlib.error,
        NotImplementedError, RuntimeError,
    ) as exc:  # fmt: skip
        why = str(exc) if len(str(exc)) <= _MAX_REASON else str(exc)[:_MAX_REASON] + " ..."
        raise ResultFileError(f"{path} is not a readable result file (corrupted?): {why}") from exc


def read_regular_file(
    path: Path, *, max_bytes: int = MAX_RESULT_BYTES, what: str = "file"
) -> bytes:
    """Return the bytes of a regular file of at most ``max_bytes``; never block on a FIFO.

    A FIFO, a device (``/dev/zero``), a folder or a socket is refused before it
    is opened, and so is a file larger than the limit.

    Parameters
    ----------
    path : Path
        The file.
    max_bytes : int, optional
        Largest size [bytes] (:data:`MAX_RESULT_BYTES`).
    what : str, optional
        What the file should hold, for the message (``"an IK-path result"``).

    Returns
    -------
    bytes
        The content.

    Raises
    ------
    ResultFileError
        If the path is missing, not a regular file, too large or unreadable.
    """
    try:
        info = os.stat(path)
    except OSError as exc:
        raise ResultFileError(f"{path}: cannot read {what}: {exc.strerror or exc}") from exc
    if not stat.S_ISREG(info.st_mode):
        raise ResultFileError(
            f"{path} is not a regular file ({file_kind(info.st_mode)}); {what} is a file"
        )
    if info.st_size > max_bytes:
        raise ResultFileError(
            f"{path} holds {info.st_size} bytes, more than the limit MAX_RESULT_BYTES = "
            f"{max_bytes} of {what}; not read"
        )
    try:
        with open(path, "rb") as handle:
            return handle.read(max_bytes + 1)[: max_bytes + 1]
    except OSError as exc:
        raise ResultFileError(f"{path}: cannot read {what}: {exc.strerror or exc}") from exc


def read_input_text(file: Path, *, max_bytes: int, what: str, name: str) -> str:
    """Return a user's input file (targets, waypoints) as text, refused as a parameter.

    :func:`read_regular_file` under ``max_bytes`` [bytes], decoded as UTF-8.

    Raises
    ------
    ParameterError
        Named ``name`` with the path as value: a missing, special or oversized
        file, or text that is not UTF-8 (the reason and the byte).
    """
    try:
        return read_regular_file(file, max_bytes=max_bytes, what=what).decode("utf-8")
    except ResultFileError as exc:
        raise ParameterError(str(exc), name=name, value=str(file)) from exc
    except UnicodeDecodeError as exc:
        raise ParameterError(
            f"{file}: not UTF-8 text ({exc.reason} at byte {exc.start})",
            name=name,
            value=str(file),
        ) from exc
