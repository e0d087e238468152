"""Canonical orderings and canonical IDs (paper Algorithms 1 and 2), batched with numpy."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import as_point_batch, lambda_matrices
from ottag_db.errors import LambdaFormatError

__all__ = [
    "CanonicalBatch",
    "CanonicalForm",
    "canonical_batch",
    "canonical_form",
    "canonical_lambda",
    "canonical_orderings",
    "canonicalize_lambdas",
    "lambda_orderings",
    "lambda_text",
    "lambda_texts",
    "mirror_lambdas",
    "parse_lambda_text",
    "relabel_lambda",
]


@dataclass(frozen=True)
class CanonicalBatch:
    """Canonical data of ``B`` point sets of ``n`` points each (all arrays numpy).

    - ``lambdas``: ``(B, n, n)`` int8 canonical λ-matrices (the ID), diagonal 0;
    - ``labelings``: ``(B, n)`` input index of the point with canonical label 0, 1, …;
    - ``minimal_orderings``: ``(B,)`` how many canonical orderings reach the minimum
      (1 ⇔ the set is in the paper's E^k and can be used for point matching);
    - ``hull_sizes``: ``(B,)`` convex-hull vertex counts (= number of canonical orderings).
    """

    lambdas: NDArray[np.int8]
    labelings: NDArray[np.int64]
    minimal_orderings: NDArray[np.int64]
    hull_sizes: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.lambdas.shape[0])

    def texts(self) -> list[str]:
        """Canonical IDs in the text form ``k:digits``."""
        return lambda_texts(self.lambdas)


@dataclass(frozen=True)
class CanonicalForm:
    """Canonical data of one point set; see :class:`CanonicalBatch` for the fields."""

    lambda_matrix: NDArray[np.int8]
    labeling: tuple[int, ...]
    minimal_orderings: int
    hull_size: int

    @property
    def k(self) -> int:
        """Number of points."""
        return int(self.lambda_matrix.shape[0])

    @property
    def unique_min(self) -> bool:
        """True when one canonical ordering alone reaches the minimum (paper's E^k)."""
        return self.minimal_orderings == 1

    @property
    def text(self) -> str:
        """The ID in the text form ``k:digits``."""
        return lambda_text(self.lambda_matrix)


def _orderings_from_lambdas(lam: NDArray[np.integer]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Canonical orderings starting at every point: ``(B, n, n)`` perms and a hull mask.

    From a hull vertex ``h`` the other points, sorted counter-clockwise (first the one with
    everything on its left), have λ(h, j) = n−2, n−3, …, 0: the label of ``j`` is simply
    ``n − 1 − λ(h, j)``, so no sort is needed. Rows of non-hull starts are garbage and
    masked out.
    """
    b, n, _ = lam.shape
    on_hull = (lam == n - 2).any(axis=2)
    pos = (n - 1) - lam.astype(np.int64)
    idx = np.arange(n)
    pos[:, idx, idx] = 0
    # Non-hull rows may hold repeated or out-of-range labels; clip to keep indexing valid.
    np.clip(pos, 0, n - 1, out=pos)
    perms = np.zeros((b, n, n), dtype=np.int64)
    np.put_along_axis(perms, pos, np.broadcast_to(idx, (b, n, n)).copy(), axis=2)
    return perms, on_hull


def canonicalize_lambdas(lam: NDArray[np.integer]) -> CanonicalBatch:
    """Canonicalize ``(B, n, n)`` λ-matrices of sets in general position (Algorithm 2).

    The ID is the lexicographically minimal λ-matrix (row-major) over the canonical
    orderings, one per hull vertex (Algorithm 1). Works on λ alone, so it also serves
    mirror images (see :func:`mirror_lambdas`) and abstract order types.

    Row 0 is ``0, n−2, …, 0`` for every ordering, so the comparison starts at row 1 and
    goes on row by row only for the sets whose orderings still tie: most sets are decided
    by their first rows, which keeps the work close to ``O(B·n²)``.

    Parameters
    ----------
    lam : ndarray of int, shape (B, n, n)
        λ-matrices of sets in general position (see
        :func:`~ottag_db.core.geometry.lambda_matrices`).

    Returns
    -------
    CanonicalBatch
        Canonical λ-matrices (the IDs), labelings, minimal-ordering counts and hull sizes.
    """
    lam = np.asarray(lam)
    b, n, _ = lam.shape
    perms, on_hull = _orderings_from_lambdas(lam)
    powers = 10 ** np.arange(n - 1, -1, -1, dtype=np.int64)  # one row is n <= 10 digits
    big = np.iinfo(np.int64).max
    alive = on_hull.copy()
    active = np.arange(b)
    for r in range(1, n):
        if active.size == 0:
            break
        sub_perms = perms[active]
        row_points = sub_perms[:, :, r]
        rows = lam[active[:, None, None], row_points[:, :, None], sub_perms]
        keys = rows.astype(np.int64) @ powers
        sub_alive = alive[active]
        keys = np.where(sub_alive, keys, big)
        sub_alive &= keys == keys.min(axis=1, keepdims=True)
        alive[active] = sub_alive
        active = active[sub_alive.sum(axis=1) > 1]
    best = alive.argmax(axis=1)
    labelings = perms[np.arange(b), best]
    canon = lam[np.arange(b)[:, None, None], labelings[:, :, None], labelings[:, None, :]]
    return CanonicalBatch(
        lambdas=canon.astype(np.int8),
        labelings=labelings,
        minimal_orderings=alive.sum(axis=1).astype(np.int64),
        hull_sizes=on_hull.sum(axis=1).astype(np.int64),
    )


def canonical_batch(points: ArrayLike) -> CanonicalBatch:
    """Canonical IDs of a batch of point sets.

    Parameters
    ----------
    points : array_like, shape (B, n, 2)
        Point sets in general position (any units; screen coordinates).

    Returns
    -------
    CanonicalBatch
        Canonical data of every set (see :func:`canonicalize_lambdas`).
    """
    pts, _ = as_point_batch(points)
    return canonicalize_lambdas(lambda_matrices(pts))


def canonical_form(points: ArrayLike) -> CanonicalForm:
    """Canonical ID, labeling, minimal-ordering count and hull size of one set.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        One point set in general position (any units; screen coordinates).

    Returns
    -------
    CanonicalForm
        Its canonical data.
    """
    pts = np.asarray(points)
    if pts.ndim != 2:
        raise ValueError("canonical_form takes one point set of shape (n, 2)")
    batch = canonical_batch(pts[None])
    return CanonicalForm(
        lambda_matrix=batch.lambdas[0],
        labeling=tuple(int(v) for v in batch.labelings[0]),
        minimal_orderings=int(batch.minimal_orderings[0]),
        hull_size=int(batch.hull_sizes[0]),
    )


def canonical_lambda(points: ArrayLike) -> str:
    """Canonical ID of one point set.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        One point set in general position (any units; screen coordinates).

    Returns
    -------
    str
        The ID in the text form ``k:digits``.
    """
    return canonical_form(points).text


def canonical_orderings(points: ArrayLike) -> list[tuple[tuple[int, ...], NDArray[np.int8]]]:
    """All canonical orderings of one set with their λ-matrices, smallest matrix first.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        One point set in general position (any units; screen coordinates).

    Returns
    -------
    list of (tuple of int, ndarray of int8)
        One ``(labeling, matrix)`` per hull vertex, smallest ``(n, n)`` matrix first;
        ``labeling[l]`` is the input index of the point with label ``l``.
    """
    return lambda_orderings(lambda_matrices(np.asarray(points)[None])[0])


def lambda_orderings(lam: NDArray[np.integer]) -> list[tuple[tuple[int, ...], NDArray[np.int8]]]:
    """:func:`canonical_orderings` of one ``(n, n)`` λ-matrix of a set in general position.

    A single-set path (no batch set-up): from hull vertex ``h`` point ``j`` gets label
    ``n − 1 − λ(h, j)`` (see :func:`_orderings_from_lambdas`); ties keep hull-vertex order.

    Parameters
    ----------
    lam : ndarray of int, shape (n, n)
        λ-matrix of one set in general position.

    Returns
    -------
    list of (tuple of int, ndarray of int8)
        As :func:`canonical_orderings`.
    """
    lam = np.asarray(lam, dtype=np.int64)
    n = lam.shape[0]
    hull = np.flatnonzero((lam == n - 2).any(axis=1))
    pos = (n - 1) - lam[hull]
    pos[np.arange(len(hull)), hull] = 0
    perms = np.zeros((len(hull), n), dtype=np.int64)
    perms[np.arange(len(hull))[:, None], pos] = np.arange(n)  # put_along_axis, without its overhead
    mats = lam[perms[:, :, None], perms[:, None, :]].astype(np.int8)
    keys = [m.tobytes() for m in mats]  # entries 0 … n−2: byte order is lexicographic order
    order = sorted(range(len(hull)), key=keys.__getitem__)
    return [(tuple(perms[o].tolist()), mats[o]) for o in order]


def mirror_lambdas(lam: NDArray[np.integer]) -> NDArray[np.int8]:
    """λ-matrices of the mirror images: left and right swap, so λ' = n − 2 − λ off the diagonal.

    Parameters
    ----------
    lam : ndarray of int, shape (..., n, n)
        λ-matrices.

    Returns
    -------
    ndarray of int8, shape (..., n, n)
        The mirror images' λ-matrices (same labels, diagonal 0).
    """
    lam = np.asarray(lam)
    n = lam.shape[-1]
    out: NDArray[np.int8] = (n - 2 - lam).astype(np.int8)
    idx = np.arange(n)
    out[..., idx, idx] = 0
    return out


def relabel_lambda(lam: NDArray[np.integer], labeling: ArrayLike) -> NDArray[np.int8]:
    """λ-matrix after relabeling: entry (a, b) is λ(labeling[a], labeling[b]).

    Parameters
    ----------
    lam : ndarray of int, shape (n, n)
        A λ-matrix.
    labeling : array_like of int, shape (n,)
        ``labeling[a]`` is the old index of the point with new label ``a``.

    Returns
    -------
    ndarray of int8, shape (n, n)
        The relabeled matrix.
    """
    perm = np.asarray(labeling, dtype=np.int64)
    return np.asarray(lam)[np.ix_(perm, perm)].astype(np.int8)


def lambda_texts(lams: NDArray[np.integer]) -> list[str]:
    """Text forms of a stack of λ-matrices.

    Parameters
    ----------
    lams : ndarray of int, shape (B, k, k)
        λ-matrices with entries 0 … 9 (k ≤ 10).

    Returns
    -------
    list of str
        ``k:digits`` per matrix (row-major, diagonal 0).
    """
    lams = np.asarray(lams)
    b, k, _ = lams.shape
    if k > 10:
        raise ValueError("the text form needs one digit per entry (k <= 10)")
    digits = (lams.reshape(b, k * k).astype(np.uint8) + ord("0")).tobytes()
    prefix = f"{k}:"
    step = k * k
    return [prefix + digits[i * step : (i + 1) * step].decode("ascii") for i in range(b)]


def lambda_text(lam: NDArray[np.integer]) -> str:
    """Text form of one λ-matrix.

    Parameters
    ----------
    lam : ndarray of int, shape (k, k)
        A λ-matrix (k ≤ 10).

    Returns
    -------
    str
        ``k:digits`` (row-major, diagonal 0).
    """
    return lambda_texts(np.asarray(lam)[None])[0]


def parse_lambda_text(text: str) -> NDArray[np.int8]:
    """Parse an ID text back into its λ-matrix.

    Parameters
    ----------
    text : str
        ``k:digits`` with 3 ≤ k ≤ 10 and ``k²`` digits (surrounding blanks ignored).

    Returns
    -------
    ndarray of int8, shape (k, k)
        The λ-matrix.

    Raises
    ------
    LambdaFormatError
        When ``text`` is not of that form or its diagonal is not 0.
    """
    head, sep, digits = text.strip().partition(":")
    if not sep or not head.isdigit():
        raise LambdaFormatError(f"{text!r} is not an ID of the form k:digits (e.g. 3:010001100)")
    k = int(head)
    if not 3 <= k <= 10:
        raise LambdaFormatError(f"{text!r}: k must be between 3 and 10")
    if len(digits) != k * k or not digits.isdigit():
        raise LambdaFormatError(f"{text!r}: expected {k * k} digits after '{k}:', got {len(digits)}")
    mat = (np.frombuffer(digits.encode("ascii"), dtype=np.uint8) - ord("0")).reshape(k, k)
    if np.any(np.diag(mat) != 0):
        raise LambdaFormatError(f"{text!r}: the diagonal of a λ-matrix must be 0")
    return mat.astype(np.int8)
