"""Transcription methods (strategy objects) turning a problem into an NLP.

* :class:`TrapezoidalCollocation` -- the study's scheme (``9n + 1`` variables
  and ``6(n - 1) + 12`` equalities for the youBot).
* :class:`HermiteSimpsonCollocation` -- separated Hermite-Simpson with a
  mid-interval torque.
* :class:`RadauCollocation` -- three-stage Radau IIA (L-stable: stiff damping).
"""

from __future__ import annotations

from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.transcription.base import TranscribedNLP, Transcription
from youbot_opt.trajopt.transcription.hermite_simpson import HermiteSimpsonCollocation
from youbot_opt.trajopt.transcription.radau import RadauCollocation
from youbot_opt.trajopt.transcription.trapezoidal import TrapezoidalCollocation

__all__ = [
    "HermiteSimpsonCollocation",
    "RadauCollocation",
    "TranscribedNLP",
    "Transcription",
    "TrapezoidalCollocation",
    "get_transcription",
]

_METHODS: dict[str, type[Transcription]] = {
    "trapezoidal": TrapezoidalCollocation,
    "hermite_simpson": HermiteSimpsonCollocation,
    "hermite-simpson": HermiteSimpsonCollocation,
    "radau": RadauCollocation,
}


def get_transcription(method: str | Transcription) -> Transcription:
    """Return a transcription object from its name (or the object itself).

    Parameters
    ----------
    method : str or Transcription
        ``"trapezoidal"``, ``"hermite_simpson"`` (or ``"hermite-simpson"``),
        ``"radau"``, or an instance.

    Returns
    -------
    Transcription
        The strategy object.

    Raises
    ------
    ParameterError
        On an unknown name; the message lists the valid ones.
    """
    if isinstance(method, Transcription):
        return method
    try:
        return _METHODS[str(method)]()
    except KeyError:
        raise ParameterError(
            f"unknown transcription {method!r}; choose one of {sorted(_METHODS)}",
            name="method",
            value=method,
        ) from None
