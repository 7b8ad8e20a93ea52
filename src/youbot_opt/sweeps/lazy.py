"""Sequences whose items are made or read when asked for: starts, jobs, tasks, stored results.

:class:`LazySequence` holds the indexing rules once (negative indices, the range
check, slices); a subclass gives ``__len__`` and :meth:`LazySequence._item`.
:class:`ListEquality` makes such a sequence equal to any sequence of equal
items, as a list is. A sweep of 10^6 starts holds none of them this way.

    class Squares(LazySequence[int]):
        def __len__(self) -> int: return 10
        def _item(self, j: int) -> int: return j * j
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar, TypeVar, overload

__all__ = ["LazySequence", "ListEquality"]

T = TypeVar("T")


class ListEquality:
    """Mixin: a lazy sequence equals any sequence of equal items, as a list does (unhashable)."""

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Sequence) or isinstance(other, str):
            return NotImplemented
        mine: Sequence[object] = self  # type: ignore[assignment]
        return len(mine) == len(other) and all(a == b for a, b in zip(mine, other, strict=True))

    __hash__ = None  # type: ignore[assignment]


class LazySequence(Sequence[T]):
    """A sequence whose item ``j`` is made by :meth:`_item` when asked for.

    ``seq[i]`` accepts ``-len <= i < len`` (else ``IndexError`` naming
    :attr:`noun` and the length); a slice is a list of the items (or
    :meth:`_slice`'s choice). Subclasses give ``__len__`` and ``_item``.
    """

    noun: ClassVar[str] = "item"
    """What an item is called in the ``IndexError`` message."""

    def _item(self, j: int) -> T:
        """Return item ``j`` (``0 <= j < len(self)``)."""
        raise NotImplementedError

    def _slice(self, s: slice) -> Sequence[T]:
        """Return the items of slice ``s`` (default: a list, each made by :meth:`_item`)."""
        return [self._item(j) for j in range(len(self))[s]]

    def _index_error(self, i: int, n: int) -> str:
        """Return the message of an index ``i`` out of range for ``n`` items."""
        return f"{n} {self.noun}(s), got index {i}"

    @overload
    def __getitem__(self, i: int) -> T: ...
    @overload
    def __getitem__(self, i: slice) -> Sequence[T]: ...
    def __getitem__(self, i: int | slice) -> T | Sequence[T]:
        if isinstance(i, slice):
            return self._slice(i)
        n = len(self)
        j = i + n if i < 0 else i
        if not 0 <= j < n:
            raise IndexError(self._index_error(i, n))
        return self._item(j)
