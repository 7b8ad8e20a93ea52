"""One line for an :class:`OSError` the system raised on a path we read or write (#29).

:func:`os_error_line` names the path (the file meant, not a temporary one) and
what it should have been: an existing folder, a writable one, a folder where a
file is in the way, free space. The command line prints it and exits 2.

    os_error_line(FileNotFoundError(2, "No such file or directory", "out/x.json"))
"""

from __future__ import annotations

import errno
from pathlib import Path

from youbot_opt._files import TMP_PREFIX

__all__ = ["os_error_line"]

_EXPECTED = {
    errno.EACCES: "a path this user may write (and read): the folder or file is read-only",
    errno.EPERM: "a path this user may write (and read): the folder or file is read-only",
    errno.EROFS: "a folder on a writable file system (this one is mounted read-only)",
    errno.ENOSPC: "free space on its disk (nothing half-written is kept; a sweep rerun "
    "with the same --out resumes where it stopped)",
    errno.EDQUOT: "free space in the disk quota (nothing half-written is kept; a sweep "
    "rerun with the same --out resumes where it stopped)",
    errno.ENOTDIR: "a folder there, but a file is in the way",
    errno.EISDIR: "a file there, but it is a folder",
    errno.EEXIST: "a folder there, but a file is in the way",
    errno.ENAMETOOLONG: "a shorter path",
    errno.ELOOP: "a path without symbolic-link loops",
}


def _meant(name: str) -> Path:
    """Return the file a temporary ``.tmp-<name>.<random>`` stands for (else ``name`` itself)."""
    path = Path(name)
    if path.name.startswith(TMP_PREFIX) and "." in path.name[len(TMP_PREFIX) :]:
        return path.with_name(path.name[len(TMP_PREFIX) :].rsplit(".", 1)[0])
    return path


def os_error_line(exc: OSError) -> str:
    """Return one line naming the path of ``exc`` and what was expected there."""
    why = exc.strerror or str(exc)
    if exc.errno is None:  # raised by us with its own message
        return str(exc)
    if exc.filename is None:
        return f"{why} (errno {exc.errno}); nothing half-written is kept"
    path = _meant(str(exc.filename))
    if exc.errno == errno.ENOENT:
        parent = path.parent
        if not parent.is_dir():
            where = f"its folder {str(parent)!r} does not exist"
            return f"cannot write {str(path)!r}: {where}; create it first"
        expected = "a folder where files can be created (this one does not take new files)"
        return f"cannot use {str(path)!r}: {why}; expected {expected}"
    expected = _EXPECTED.get(exc.errno or 0, "a regular file or folder this user may use")
    return f"cannot use {str(path)!r}: {why}; expected {expected}"
