"""Sparse CasADi matrices from entries drawn from stacked source vectors: :class:`SparseEntries`.

Each entry ``(row, col)`` takes a scaled value at a position of one of the
sources (MX column vectors, e.g. a mapped kernel's outputs); entries at the
same ``(row, col)`` are summed. The pattern and the index maps are numeric
(numpy), the matrix is a few ``GetNonzeros`` nodes: no symbolic work per entry.
The NLP's Jacobian and Hessian are assembled so
(:mod:`~youbot_opt.trajopt.transcription.stencil`).

    entries = SparseEntries()
    entries.add(values, rows, cols, np.arange(values.numel()))
    matrix = entries.matrix(n_rows, n_cols)
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Indices", "SparseEntries", "upper_entries"]

Indices = NDArray[np.int64]
"""An integer index array."""


def upper_entries(width: int, count: int, z: Indices) -> tuple[Indices, Indices, Indices]:
    """Return the upper-triangle entries of ``count`` dense symmetric blocks stored side by side.

    Parameters
    ----------
    width : int
        Size of each ``width x width`` block.
    count : int
        Number of blocks, stored as one ``(width, width count)`` matrix.
    z : ndarray, shape (count, width)
        Each block's coordinates: the rows (and columns) of its entries in the
        assembled matrix.

    Returns
    -------
    rows, cols, positions : ndarray
        The entries' rows and columns in the assembled matrix (``rows <= cols``)
        and their column-major positions in the stored matrix.
    """
    i, j = np.triu_indices(width)
    p = np.arange(count)[:, None]
    a, b = z[p, i[None, :]], z[p, j[None, :]]
    pos = (p * width + j[None, :]) * width + i[None, :]
    return np.minimum(a, b).ravel(), np.maximum(a, b).ravel(), pos.ravel()


class SparseEntries:
    """Entries ``(row, col)`` of a sparse matrix drawn from a stack of source vectors."""

    def __init__(self) -> None:
        self.rows: list[Indices] = []
        self.cols: list[Indices] = []
        self.src: list[Indices] = []
        self.scale: list[NDArray[np.float64]] = []
        self.values: list[ca.MX] = []
        self.size = 0

    def add(
        self,
        values: ca.MX,
        rows: ArrayLike,
        cols: ArrayLike,
        pos: ArrayLike,
        scale: ArrayLike = 1.0,
    ) -> None:
        """Add entries ``(rows, cols)``: ``scale`` times the entries ``pos`` of ``values``.

        Parameters
        ----------
        values : casadi.MX
            A column vector of sources.
        rows, cols, pos : array_like of int
            The entries' rows and columns, and the positions in ``values`` of their values.
        scale : array_like of float
            A factor of each entry (broadcast to ``rows``' shape).
        """
        rows = np.asarray(rows, dtype=np.int64)
        self.rows.append(rows.ravel())
        self.cols.append(np.asarray(cols, dtype=np.int64).ravel())
        self.src.append(self.size + np.asarray(pos, dtype=np.int64).ravel())
        self.scale.append(np.broadcast_to(np.asarray(scale, dtype=float), rows.shape).ravel())
        self.values.append(values)
        self.size += int(values.numel())

    def matrix(self, n_rows: int, n_cols: int) -> ca.MX:
        """Return the sparse MX matrix of the entries, duplicates summed.

        Its nonzeros are sums of layers, each a gather of the sources (one
        ``GetNonzeros``) times its scale: layer ``j`` holds the ``j``-th entry
        of each nonzero (a zero appended to the sources pads the shorter sums).
        """
        rows, cols = np.concatenate(self.rows), np.concatenate(self.cols)
        src, scale = np.concatenate(self.src), np.concatenate(self.scale)
        # the entries sorted in compressed-column order; each one's nonzero and rank in it
        keys = cols * n_rows + rows
        order = np.argsort(keys, kind="stable")
        ordered = keys[order]
        first = np.ones(ordered.size, dtype=bool)
        first[1:] = ordered[1:] != ordered[:-1]
        unique = ordered[first]
        nz = np.cumsum(first) - 1
        rank = np.arange(ordered.size) - np.flatnonzero(first)[nz]
        colind = np.searchsorted(unique // n_rows, np.arange(n_cols + 1))
        pattern = ca.Sparsity(n_rows, n_cols, colind.tolist(), (unique % n_rows).tolist())
        sources = ca.vertcat(*self.values, ca.MX(1, 1))  # the zero: index self.size
        total: ca.MX | None = None
        for layer in range(int(rank.max(initial=-1)) + 1):
            at = rank == layer
            index = np.full(unique.size, self.size, dtype=np.int64)
            index[nz[at]] = src[order[at]]
            term = sources[index.tolist()]
            factor = np.ones(unique.size)
            factor[nz[at]] = scale[order[at]]
            if np.any(factor != 1.0):
                term = term * ca.DM(factor.tolist())
            total = term if total is None else total + term
        values = ca.MX(0, 1) if total is None else total
        return ca.MX(pattern, values)
