"""How to load a robot again from a file that may have moved: :class:`RobotSource`.

Result files record their robot as a :class:`RobotSource`: a robot name, or a
URDF by its absolute path, its path relative to the result's folder and the
SHA-256 of its bytes (:func:`urdf_digest`), with the loader options (package
folders, locked joints, strictness). :meth:`RobotSource.load` tries the recorded
path, then the relative one, and takes only a file of the recorded content.
Rationale: docs/design.md, "youbot_opt.robot.source".

>>> data = RobotSource.of(robot).to_json(folder="runs/a")  # doctest: +SKIP
>>> robot = RobotSource.from_json(data).load(folder="moved/a")  # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from youbot_opt._checks import iterable, to_float
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ModelError, ParameterError, RobotNotFound
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.payload import Payload

__all__ = ["ROBOT_FILE_SUFFIXES", "RobotSource", "urdf_digest"]

ROBOT_FILE_SUFFIXES = (".urdf", ".xml", ".mjcf")
"""Suffixes of the robot files a recorded source may name (URDF, MJCF); nothing else is read."""

_log = logging.getLogger(__name__)

_SHA256_HEX = re.compile(r"[0-9a-f]{64}")
_SHOWN = 12  # hex digits of a SHA-256 shown in messages


def urdf_digest(path: str | os.PathLike[str], robot_name: str) -> str:
    """Return the SHA-256 (hex) of a URDF file's bytes: what identifies the robot.

    It does not depend on where the file lies, so a file moved or copied to
    another machine is the same robot, and an edited file another one.

    Parameters
    ----------
    path : str or path-like
        The URDF file.
    robot_name : str
        The robot's name, for the error message.

    Returns
    -------
    str
        64 lower-case hex digits.

    Raises
    ------
    ParameterError
        If the file cannot be read (the message names it and the robot).
    """
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as exc:
        raise ParameterError(
            f"cannot read the URDF {path} of robot {robot_name!r} to identify it: {exc}",
            name="robot",
            value=str(path),
        ) from exc


def _relative(path: str, folder: Path) -> str:
    """``path`` relative to ``folder`` (may hold ``..``); absolute when there is none."""
    try:
        return os.path.relpath(Path(path).resolve(), folder)
    except ValueError:  # another drive (Windows): no relative path exists
        return str(Path(path).resolve())


@dataclass(frozen=True, slots=True, kw_only=True)
class RobotSource:
    """How to load a robot again: :func:`~youbot_opt.robot.load.load_model` arguments.

    Attributes
    ----------
    source : str
        A name of :func:`~youbot_opt.robot.catalogue.available_robots`, or the
        absolute path of a URDF file.
    package_dirs : tuple of str
        Folders for ``package://`` references, absolute.
    lock_joints : tuple of (str, float)
        Locked joints and their positions in [rad] or [m].
    strict : bool
        The loader's inertia policy (``False``: ``--lenient``).
    urdf_sha256 : str or None
        SHA-256 (hex) of the URDF file's bytes; None for a robot name, and in
        files written before it was recorded (then the file is not checked).
    relative_source : str or None
        The URDF's path relative to the folder of the file this was written
        into (:meth:`to_json` with ``folder``); None for a name or when not written so.
    relative_package_dirs : tuple of str
        Each of ``package_dirs`` relative to that folder; empty when not written so.
    payload : Payload or None
        The payload the robot carries (:meth:`RobotModel.with_payload`), attached again on load.
    """

    source: str
    package_dirs: tuple[str, ...] = ()
    lock_joints: tuple[tuple[str, float], ...] = ()
    strict: bool = True
    urdf_sha256: str | None = None
    relative_source: str | None = None
    relative_package_dirs: tuple[str, ...] = ()
    payload: Payload | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.source, str) or not self.source:
            raise ParameterError(
                f"source must be a robot name or a URDF path, got {self.source!r}",
                name="source",
                value=self.source,
            )
        digest = self.urdf_sha256
        if digest is not None and not (isinstance(digest, str) and _SHA256_HEX.fullmatch(digest)):
            raise ParameterError(
                f"urdf_sha256 must be 64 lower-case hex digits or None, got {digest!r}",
                name="urdf_sha256",
                value=digest,
            )
        if self.relative_source is not None and digest is None:
            raise ParameterError(
                f"relative_source {self.relative_source!r} needs the urdf_sha256 of its file",
                name="relative_source",
                value=self.relative_source,
            )
        n, m = len(self.package_dirs), len(self.relative_package_dirs)
        if m not in (0, n):
            raise ParameterError(
                f"relative_package_dirs must hold one path per package dir ({n}) or none, "
                f"got {m}: {list(self.relative_package_dirs)}",
                name="relative_package_dirs",
                value=self.relative_package_dirs,
            )

    @classmethod
    def of(cls, robot: RobotModel, *, strict: bool | None = None) -> RobotSource:
        """Describe a loaded robot: its name if it was loaded by name, else its URDF file.

        A robot loaded from a file is recorded by the file's path and SHA-256
        whatever its ``<robot name>`` is: a file named ``panda`` is not the
        catalogue's panda (:attr:`RobotModel.catalogue_name`).

        Parameters
        ----------
        robot : RobotModel
            The robot, as :func:`~youbot_opt.robot.load.load_model` returned it.
        strict : bool, optional
            The loader's inertia policy; default: the robot's own (``robot.strict``).

        Returns
        -------
        RobotSource
            Name, or absolute URDF path and its SHA-256, and the loader options.

        Raises
        ------
        ParameterError
            If the robot has neither (built from parameters in memory), or its
            URDF file can no longer be read.
        """
        if robot.catalogue_name is not None:
            source, digest = robot.catalogue_name, None
        elif robot.urdf_path is not None:
            path = Path(robot.urdf_path).resolve()
            source, digest = str(path), urdf_digest(path, robot.name)
        else:
            raise ParameterError(
                f"robot {robot.name!r} has no URDF file and was not loaded by name; "
                "a result file cannot name how to load it again",
                name="robot",
                value=robot.name,
            )
        return cls(
            source=source,
            package_dirs=tuple(dict.fromkeys(str(Path(p).resolve()) for p in robot.package_dirs)),
            lock_joints=tuple((str(k), float(v)) for k, v in robot.locked_joints),
            strict=robot.strict if strict is None else bool(strict),
            urdf_sha256=digest,
            payload=robot.payload,
        )

    def candidates(self, folder: str | os.PathLike[str] | None = None) -> tuple[Path, ...]:
        """Return the URDF paths :meth:`load` tries for a file read from ``folder``, in order.

        The recorded absolute path, then the recorded relative path taken from
        ``folder`` (when both are known and it differs); empty for a robot name.
        """
        if self.urdf_sha256 is None:
            return ()
        paths = [Path(self.source)]
        if folder is not None and self.relative_source is not None:
            moved = Path(os.path.normpath(Path(folder).resolve() / self.relative_source))
            if moved != paths[0]:
                paths.append(moved)
        return tuple(paths)

    def locate(self, folder: str | os.PathLike[str] | None = None) -> str:
        """Return what :meth:`load` gives the loader: the name, or the URDF file to use.

        Parameters
        ----------
        folder : str or path-like, optional
            The folder of the file this source was read from.

        Returns
        -------
        str
            The robot name, or the first of :meth:`candidates` that exists and
            has the recorded content; the recorded path as it is for a source
            without ``urdf_sha256`` (files written before it was recorded).

        Raises
        ------
        RobotNotFound
            If no candidate exists; the message names every path tried.
        ModelError
            If candidates exist but none has the recorded content; the message
            names each and both SHA-256 (first 12 hex digits). Only files with
            a robot file's suffix (:data:`ROBOT_FILE_SUFFIXES`) are read: a
            result file may name any path (``../../etc/shadow``), which is named
            and not read.
        """
        if self.urdf_sha256 is None:
            return self.source
        tried = self.candidates(folder)
        found = [p for p in tried if p.is_file()]
        if not found:
            where = self._tried(tried, folder)
            raise RobotNotFound(f"the robot's URDF is not found: tried {where}", path=self.source)
        differ = []
        for path in found:
            if path.suffix.lower() not in ROBOT_FILE_SUFFIXES:  # never read what is no robot file
                differ.append(f"{path} is not a robot file (suffix not in {ROBOT_FILE_SUFFIXES})")
                continue
            digest = urdf_digest(path, Path(self.source).stem)
            if digest == self.urdf_sha256:
                return str(path)
            differ.append(f"{path} has SHA-256 {digest[:_SHOWN]}...")
        missing = [str(p) for p in tried if p not in found]
        raise ModelError(
            f"the robot's URDF has changed: {'; '.join(differ)}, the file recorded "
            f"{self.urdf_sha256[:_SHOWN]}..."
            + (f" (not found: {', '.join(missing)})" if missing else ""),
            path=str(found[0]),
        )

    def _tried(self, tried: tuple[Path, ...], folder: str | os.PathLike[str] | None) -> str:
        parts = [f"{tried[0]} (the recorded path)"]
        if len(tried) > 1:
            parts.append(
                f"{tried[1]} (the recorded relative path {self.relative_source!r} "
                f"from the folder {Path(folder or '.').resolve()})"
            )
        elif self.relative_source is not None and folder is None:
            parts.append(f"no relative path ({self.relative_source!r}: no folder given)")
        return " and ".join(parts)

    def _package_dirs(
        self, folder: str | os.PathLike[str] | None
    ) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(folders to use, folders found nowhere); as recorded for an older source."""
        if not self.relative_package_dirs:
            return self.package_dirs, ()
        use, missing = [], []
        base = None if folder is None else Path(folder).resolve()
        for recorded, relative in zip(self.package_dirs, self.relative_package_dirs, strict=True):
            moved = None if base is None else os.path.normpath(base / relative)
            if Path(recorded).is_dir():
                use.append(recorded)
            elif moved is not None and Path(moved).is_dir():
                use.append(moved)
            else:
                missing.append(recorded if moved is None else f"{recorded} or {moved}")
        if missing:
            # The loader adds its own robot's folders again; a mesh needing one fails by name.
            _log.info("package folders found nowhere, left out: %s", missing)
        return tuple(use), tuple(missing)

    def load(
        self, tip_frame: str | None = None, *, folder: str | os.PathLike[str] | None = None
    ) -> RobotModel:
        """Load the robot (:func:`~youbot_opt.robot.load.load_model`).

        Parameters
        ----------
        tip_frame : str, optional
            End-effector frame; the loader's default otherwise.
        folder : str or path-like, optional
            The folder of the file this source was read from: the URDF and
            each package folder not at its recorded path are looked for at
            their recorded paths relative to it (:meth:`locate`). A package
            folder found nowhere is left out (the loader adds the folders of
            its own robots again).

        Returns
        -------
        RobotModel
            The robot, loaded with the recorded options.

        Raises
        ------
        RobotNotFound, ModelError
            As :meth:`locate`, or the loader's error (naming the package
            folders left out, if any).
        ParameterError
            As the loader (e.g. a locked joint the file no longer has).
        """
        source = self.locate(folder)
        dirs, missing = self._package_dirs(folder)
        if self.urdf_sha256 is not None:  # the loader adds the file's own folder itself
            dirs = tuple(d for d in dirs if Path(d) != Path(source).parent)
        try:
            return load_model(
                source,
                tip_frame=tip_frame,
                package_dirs=dirs,
                strict=self.strict,
                lock_joints=dict(self.lock_joints) or None,
                payload=self.payload,
            )
        except ModelError as exc:
            if not missing:
                raise
            raise ModelError(
                f"{exc} (package folders left out, found neither at their recorded path "
                f"nor relative to the file's folder: {', '.join(missing)})",
                path=source,
            ) from exc

    def to_json(self, *, folder: str | os.PathLike[str] | None = None) -> JSONDict:
        """JSON-ready form.

        Parameters
        ----------
        folder : str or path-like, optional
            The folder of the file it is written into: the URDF's path and
            each package folder's are written relative to it too (``..``
            allowed), so that the file still loads after both moved together.

        Returns
        -------
        dict
            ``source``, ``package_dirs``, ``lock_joints``, ``strict``,
            ``urdf_sha256``, ``relative_source``, ``relative_package_dirs`` and
            ``payload`` (:meth:`Payload.to_json`, or None).
        """
        relative_source, relative_dirs = self.relative_source, self.relative_package_dirs
        if folder is not None:
            base = Path(folder).resolve()
            relative_source = None if self.urdf_sha256 is None else _relative(self.source, base)
            relative_dirs = tuple(_relative(d, base) for d in self.package_dirs)
        return {
            "source": self.source,
            "package_dirs": list(self.package_dirs),
            "lock_joints": [[k, v] for k, v in self.lock_joints],
            "strict": self.strict,
            "urdf_sha256": self.urdf_sha256,
            "relative_source": relative_source,
            "relative_package_dirs": list(relative_dirs),
            "payload": None if self.payload is None else self.payload.to_json(),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, object]) -> RobotSource:
        """Inverse of :meth:`to_json`; older forms (without digest and relative paths) too.

        Raises
        ------
        KeyError, TypeError, ValueError
            If ``data`` is not such a form (``ParameterError`` is a ValueError).
        """
        digest, relative = data.get("urdf_sha256"), data.get("relative_source")
        source = str(data["source"])  # read in the order the fields are listed
        package_dirs = tuple(str(p) for p in iterable(data.get("package_dirs", ())))
        pairs = (iterable(pair) for pair in iterable(data.get("lock_joints", ())))
        lock_joints = tuple((str(k), to_float(v)) for k, v in pairs)
        strict = bool(data.get("strict", True))
        relative_dirs = iterable(data.get("relative_package_dirs") or ())
        payload = data.get("payload")
        if payload is not None and not isinstance(payload, Mapping):
            raise TypeError(f"payload must be a JSON object or null, got {payload!r}")
        return cls(
            source=source,
            package_dirs=package_dirs,
            lock_joints=lock_joints,
            strict=strict,
            urdf_sha256=None if digest is None else str(digest),
            relative_source=None if relative is None else str(relative),
            relative_package_dirs=tuple(str(p) for p in relative_dirs),
            payload=None if payload is None else Payload.from_json(payload),
        )
