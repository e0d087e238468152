"""Soft decoding: the near-collinear triples of a low-margin reading flipped, each candidate verified.

A reading whose smallest point-to-line distance is under ``min_margin_px`` is ambiguous, not
wrong: the orientation of each *ambiguous* triple (one of its points nearer than that to the
line through the other two) may have been measured on the wrong side. Flipping one or two of
those orientations in the reading's chirotope gives the order types within one or two flips
of the reading along exactly those triples — the reading's neighbours in the flip graph
(:mod:`ottag_db.core.flips`) that the measurement cannot rule out. Each one the lookup holds is
verified projectively against its stored geometry; the identification stage
(:mod:`ottag_db.decode.identify`) accepts a candidate only under the rule of :func:`choose`.

The enumeration works on the λ-matrix (a flip moves three of its entries by one, as in
:func:`ottag_db.core.flips.flip_neighbours`), canonicalizes it (Algorithm 2) and, before a
candidate is verified, confirms that the flipped chirotope, relabeled, is the stored
realization's (:func:`confirms`): a flipped chirotope that no point set realizes can never be
reported. A corrected reading must also have the triangles printed for that realization
(:func:`layout_matches`): a tag that lost a vertex (two close vertices merged) or gained one
reads as a well-fitting set of k − 1 or k + 1 points, which verification at a few pixels per
tag cannot tell from a real tag of that k, but its triangles are not that tag's. On a small
data area the detector also has a corrected reading read the same by model
(:func:`~ottag_db.decode.model_match.confirm_by_model`): tags 40 px wide whose sliver tips merged
read as look-alikes of fewer points, triangles and placement included.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import lambda_orderings, lambda_text
from ottag_db.core.flips import flip_lambdas
from ottag_db.core.geometry import orientation_tensor
from ottag_db.core.single_set import OrientationTable
from ottag_db.decode.verify import SideLines

__all__ = [
    "FlipReading",
    "Scored",
    "SoftChoice",
    "ambiguous_triples",
    "choose",
    "confirms",
    "flip_readings",
    "layout_matches",
    "observed_triangles",
]

_F64 = NDArray[np.float64]
Triple = tuple[int, int, int]


@dataclass(frozen=True)
class FlipReading:
    """One candidate reading of a measured set: the reading with ``flips`` reversed.

    - ``flips``: the triples (input point indices, ascending) whose orientation is reversed;
      empty for the reading as measured;
    - ``lambda_text``: canonical ID ``k:digits`` of the flipped chirotope;
    - ``minimal``: the labelings reaching that ID (``labeling[l]`` = input index of the point
      with canonical label ``l``), as :func:`ottag_db.decode.verify.verify` takes them.
    """

    flips: tuple[Triple, ...]
    lambda_text: str
    minimal: tuple[tuple[int, ...], ...]


@dataclass(frozen=True)
class Scored:
    """A verified candidate for :func:`choose`: whether verification accepted it (``passed``)
    and its fit ``error`` (px: the largest point–line distance of its best homography fit,
    ``inf`` when no realization could be fitted)."""

    passed: bool
    error: float


def ambiguous_triples(table: OrientationTable, threshold: float) -> list[Triple]:
    """The triples of a reading with a point nearer than ``threshold`` to the line of the other two.

    Parameters
    ----------
    table : OrientationTable
        The reading's orientation table (:func:`ottag_db.core.single_set.orientation_table`).
    threshold : float
        Distance (unit of the points, px in the decoder): ``min_margin_px``.

    Returns
    -------
    list of (int, int, int)
        Ascending index triples, nearest to collinear first (ties by index).
    """
    first, second = table.pairs.first, table.pairs.second
    rows, cols = np.nonzero(table.distance < threshold)
    best: dict[Triple, float] = {}
    for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
        a, b, p = sorted((int(first[r]), int(second[r]), int(c)))
        tri = (a, b, p)
        d = float(table.distance[r, c])
        best[tri] = min(d, best.get(tri, d))
    return sorted(best, key=lambda t: (best[t], t))


def flip_readings(table: OrientationTable, triples: Sequence[Triple], max_flips: int) -> list[FlipReading]:
    """The reading and every reading with 1 … ``max_flips`` of ``triples`` reversed.

    Reversing the orientation of ``(a, b, c)`` moves one point of the triple across the line
    of the other two: λ(a, b), λ(b, c), λ(c, a) change by one unit and their transposes by the
    opposite unit (the three directed lines of the triple lose or gain that point). Readings
    whose flipped λ-matrix is not that of any order type (a hull row that is not a
    permutation: no canonical ordering) are left out; so is a second reading with the same ID
    and the same labelings as an earlier one.

    Parameters
    ----------
    table : OrientationTable
        The reading's orientation table (margin > 0).
    triples : sequence of (int, int, int)
        Ascending index triples that may be reversed (:func:`ambiguous_triples`).
    max_flips : int
        Largest number of triples reversed at once (0: only the reading as measured).

    Returns
    -------
    list of FlipReading
        The reading as measured first, then by number of flips and the order of ``triples``.
    """
    lam = table.lambda_matrix()
    k = lam.shape[0]
    index = {(int(a), int(b)): q for q, (a, b) in enumerate(zip(table.pairs.first, table.pairs.second, strict=True))}
    out: list[FlipReading] = []
    seen: set[tuple[str, tuple[tuple[int, ...], ...]]] = set()
    for n in range(max_flips + 1):
        for subset in combinations(triples, n):
            flipped = lam[None]
            for a, b, c in subset:
                # screen convention: c is left of a→b when the cross product is negative
                flipped = flip_lambdas(flipped, [a], [b], [c], [table.cross[index[(a, b)], c] < 0])
            reading = _reading(flipped[0], k, subset)
            if reading is None:
                continue
            key = (reading.lambda_text, reading.minimal)
            if key not in seen:
                seen.add(key)
                out.append(reading)
    return out


def _reading(lam: NDArray[np.int64], k: int, flips: tuple[Triple, ...]) -> FlipReading | None:
    """Canonical ID and minimal labelings of a (flipped) λ-matrix; None when it is no order
    type's (entries outside 0 … k−2, or a hull vertex whose row does not order the others)."""
    off = ~np.eye(k, dtype=bool)
    if (lam[off] < 0).any() or (lam[off] > k - 2).any() or ((lam + lam.T)[off] != k - 2).any():
        return None
    hull = np.flatnonzero((lam == k - 2).any(axis=1))
    if len(hull) < 3:
        return None
    for h in hull:
        row = np.delete(lam[h], h)
        if not np.array_equal(np.sort(row), np.arange(k - 1)):
            return None
    orderings = lambda_orderings(lam)
    best = orderings[0][1].tobytes()
    minimal = tuple(lab for lab, mat in orderings if mat.tobytes() == best)
    return FlipReading(flips, lambda_text(orderings[0][1]), minimal)


def confirms(points: _F64, flips: Sequence[Triple], labeling: Sequence[int], realization: _F64) -> bool:
    """Whether the measured chirotope with ``flips`` reversed is that of ``realization``.

    Parameters
    ----------
    points : numpy.ndarray
        ``(k, 2)`` measured points (input order).
    flips : sequence of (int, int, int)
        Triples of input indices whose orientation is reversed.
    labeling : sequence of int
        ``labeling[l]`` = input index of the point with canonical label ``l``.
    realization : numpy.ndarray
        ``(k, 2)`` stored realization, rows in canonical label order.

    Returns
    -------
    bool
        True when every triple has the same orientation in both (and neither has three
        collinear points).
    """
    meas = np.sign(orientation_tensor(points)[0])
    for a, b, c in flips:
        for x, y, z in ((a, b, c), (b, c, a), (c, a, b), (b, a, c), (a, c, b), (c, b, a)):
            meas[x, y, z] = -meas[x, y, z]
    lab = np.asarray(labeling, dtype=np.intp)
    relabeled = meas[lab[:, None, None], lab[None, :, None], lab[None, None, :]]
    model = np.sign(orientation_tensor(realization)[0])
    return bool(np.array_equal(relabeled, model))


@dataclass(frozen=True)
class SoftChoice:
    """Outcome of :func:`choose`: ``index`` of the accepted candidate, or None with ``detail``
    saying why none is (appended to the ``low_margin`` rejection's detail)."""

    index: int | None
    detail: str = ""


def choose(candidates: Sequence[Scored], bound: float, gap: float) -> SoftChoice:
    """The acceptance rule of soft decoding.

    A candidate is accepted only when it is the *only* one that passed verification and its
    fit error is below the bound and below every other candidate's error by at least
    ``gap · bound`` (the reprojection bound stands in for a competitor that was not fitted
    at all, so a lone candidate must also pass with that much to spare).

    Parameters
    ----------
    candidates : sequence of Scored
        Every candidate the lookup holds, verified.
    bound : float
        The reprojection bound of the candidate (px).
    gap : float
        ``DetectorParams.soft_min_fit_gap``: the required lead as a fraction of ``bound``.

    Returns
    -------
    SoftChoice
        The accepted candidate's index, or None and why none is.
    """
    passing = [i for i, c in enumerate(candidates) if c.passed]
    if not passing:
        return SoftChoice(None, f"none of {len(candidates)} candidates verifies")
    if len(passing) > 1:
        return SoftChoice(None, f"{len(passing)} of {len(candidates)} candidates verify")
    win = passing[0]
    err = candidates[win].error
    runner = min([bound] + [c.error for i, c in enumerate(candidates) if i != win])
    if runner - err < gap * bound:
        return SoftChoice(None, f"fit {err:.2f} px, next {runner:.2f} px: lead below {gap * bound:.2f} px")
    return SoftChoice(win)


def observed_triangles(lines: SideLines) -> frozenset[frozenset[int]] | None:
    """The detected triangles as sets of point indices, from the side lines the points share.

    Each triangle side is one fitted line, listed among the lines of both its end points
    (the same values: :func:`ottag_db.decode.detector.read_quad` slices them from one array);
    three points pairwise joined by such lines are a triangle.

    Parameters
    ----------
    lines : SideLines
        ``lines[i]``: the side lines through point ``i``.

    Returns
    -------
    frozenset of frozenset of int or None
        The triangles; None when a line does not join exactly two points or a joined pair is
        in no triangle (the structure is not known).
    """
    owners: dict[tuple[float, float, float], list[int]] = {}
    for i, (normals, offsets) in enumerate(lines):
        for (nx, ny), c in zip(normals.tolist(), offsets.tolist(), strict=True):
            owners.setdefault((nx, ny, c), []).append(i)
    adj: dict[int, set[int]] = {}
    for pts in owners.values():
        if len(pts) != 2 or pts[0] == pts[1]:
            return None
        adj.setdefault(pts[0], set()).add(pts[1])
        adj.setdefault(pts[1], set()).add(pts[0])
    tris = {frozenset((a, b, c)) for a in adj for b in adj[a] for c in adj[a] & adj[b] if a < b < c}
    covered = {frozenset(pair) for t in tris for pair in combinations(sorted(t), 2)}
    if any(frozenset((a, b)) not in covered for a in adj for b in adj[a]):
        return None
    return frozenset(tris)


def layout_matches(
    observed: frozenset[frozenset[int]], layout: Sequence[Sequence[int]], labeling: Sequence[int]
) -> bool:
    """Whether the detected triangles are a stored layout under a labeling.

    Parameters
    ----------
    observed : frozenset of frozenset of int
        Detected triangles (point indices, :func:`observed_triangles`).
    layout : sequence of (int, int, int)
        Printed triangles as canonical labels (``LookupEntry.layouts[r]``).
    labeling : sequence of int
        ``labeling[l]`` = input index of the point with canonical label ``l``.

    Returns
    -------
    bool
        True when both are the same set of triangles.
    """
    return {frozenset(labeling[label] for label in tri) for tri in layout} == observed
