"""Exception and warning tree of youbot_opt.

Every error raised on purpose by the toolkit derives from :class:`YoubotOptError`,
so ``except YoubotOptError`` catches exactly the toolkit's own complaints. Messages
say what was wrong, the offending value, and what would have been valid; the same
facts are kept as attributes where callers may want them programmatically.
"""

from __future__ import annotations

__all__ = [
    "YoubotOptError",
    "ParameterError",
    "ModelError",
    "RobotNotFound",
    "FrameNotFound",
    "TranscriptionError",
    "SolveFailed",
    "UnreachableTarget",
    "ResultFileError",
    "ViewerError",
    "YoubotOptWarning",
    "URDFError",
    "URDFSyntaxError",
    "UnsafeURDFError",
    "UnsafePathError",
    "ResourceNotFoundError",
    "URDFStructureError",
    "InvalidModelError",
]


class YoubotOptError(Exception):
    """Base class of every error raised by youbot_opt."""


class ParameterError(YoubotOptError, ValueError):
    """A user-supplied value has the wrong shape, sign, range or type.

    Attributes
    ----------
    name : str or None
        Name of the offending argument or field, when known.
    value : object
        The offending value, when known.
    """

    def __init__(self, message: str, *, name: str | None = None, value: object = None) -> None:
        super().__init__(message)
        self.name = name
        self.value = value


class ModelError(YoubotOptError):
    """A robot description cannot be loaded or describes an invalid model.

    Attributes
    ----------
    path : str or None
        File the model came from, when known.
    """

    def __init__(self, message: str, *, path: str | None = None) -> None:
        super().__init__(message)
        self.path = path


class RobotNotFound(ModelError, LookupError):
    """A robot name or URDF path does not resolve; the message lists what exists.

    Attributes
    ----------
    available : tuple of str
        Names that would have been accepted.
    """

    def __init__(
        self, message: str, *, available: tuple[str, ...] = (), path: str | None = None
    ) -> None:
        super().__init__(message, path=path)
        self.available = available


class FrameNotFound(ModelError, LookupError):
    """A frame name is not in the model; the message lists the model's frames.

    Attributes
    ----------
    frame : str
        The requested frame name.
    available : tuple of str
        Frame names the model has.
    """

    def __init__(self, frame: str, available: tuple[str, ...]) -> None:
        super().__init__(f"frame {frame!r} not found; the model has frames: {', '.join(available)}")
        self.frame = frame
        self.available = available


class TranscriptionError(YoubotOptError):
    """A transcription (collocation scheme) cannot be built for the given problem."""


class SolveFailed(YoubotOptError):
    """Raised by ``result.raise_for_status()`` when a solve did not succeed.

    Attributes
    ----------
    result : object
        The failed result object, with the best iterate the solver reached.
    """

    def __init__(self, message: str, *, result: object = None) -> None:
        super().__init__(message)
        self.result = result


class UnreachableTarget(YoubotOptError):
    """An end-effector target lies outside the arm's reachable set.

    Attributes
    ----------
    index : int
        Index of the target in the problem's list (0-based).
    target : object
        The target position in [m] (or the chain's length unit).
    verdict : object
        The reachability verdict object with the reach limits and nearest point.
    """

    def __init__(self, message: str, *, index: int, target: object, verdict: object = None) -> None:
        super().__init__(message)
        self.index = index
        self.target = target
        self.verdict = verdict


class ResultFileError(YoubotOptError):
    """A saved result file is missing, corrupted, or of an unsupported schema version."""


class ViewerError(YoubotOptError):
    """The meshcat viewer server cannot be started, reached or stopped.

    Attributes
    ----------
    url : str or None
        The server's ZeroMQ address, when known.
    """

    def __init__(self, message: str, *, url: str | None = None) -> None:
        super().__init__(message)
        self.url = url


class YoubotOptWarning(UserWarning):
    """Recoverable problem worth the user's attention (e.g. a loosened assumption)."""


class URDFError(ModelError):
    """A robot description (or a file it references) breaks a rule of the strict loader.

    Attributes
    ----------
    path : str or None
        File that breaks the rule (the URDF, or the mesh that references a texture).
    element : str or None
        The offending element, e.g. ``"<mass> of link 'arm_link_1'"``.
    line : int or None
        1-based line of the element in ``path``, when known.
    rule : str
        The rule that was broken, in words.
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | None = None,
        element: str | None = None,
        line: int | None = None,
        rule: str = "",
    ) -> None:
        super().__init__(message, path=path)
        self.element = element
        self.line = line
        self.rule = rule


class URDFSyntaxError(URDFError):
    """The file is not well-formed XML (malformed, truncated, badly encoded)."""


class UnsafeURDFError(URDFError):
    """The file uses an XML feature refused for safety (DOCTYPE, entities) or is not a file."""


class UnsafePathError(URDFError):
    """A mesh or texture reference resolves outside the allowed package directories.

    Also raised for URL schemes other than ``package://`` and ``file://``, for
    references that resolve to something other than a regular file (a device,
    a FIFO, a directory) and for mesh formats the loader does not accept.
    """


class ResourceNotFoundError(URDFError):
    """A mesh or texture reference is allowed but names no existing file."""


class URDFStructureError(URDFError):
    """The XML is not a URDF kinematic tree (root, names, parent/child links, loops)."""


class InvalidModelError(URDFError):
    """The description is a tree but not a physically valid model.

    Raised for malformed or non-finite numbers, negative masses, inertias that
    no mass distribution can have, zero joint axes, inconsistent joint limits,
    a loaded model that disagrees with its file, and a joint-space inertia
    matrix that is not positive definite.
    """
