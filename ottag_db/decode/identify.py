"""Identification stage: a point hypothesis → canonical ID → lookup entry → verification."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import lambda_text
from ottag_db.core.lookup import LookupEntry, TagLookup
from ottag_db.core.single_set import margin, orientation_table, read_set
from ottag_db.core.types import Polarity
from ottag_db.decode.profile import StageClock
from ottag_db.decode.types import Detection, DetectorParams, Quad, Rejection
from ottag_db.decode.verify import SideLines, apply_homography, verify

__all__ = ["Catalogue", "identify"]

_F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Catalogue:
    """What identification reads besides the points: the ``lookup``, the point counts ``ks`` it
    holds (taken once, the lookup is fixed for a detector's life) and the ``params``."""

    lookup: TagLookup
    ks: frozenset[int]
    params: DetectorParams


def identify(
    pts: _F64, lines: SideLines, corners: _F64, quad: Quad, catalogue: Catalogue, clock: StageClock
) -> Detection | Rejection:
    """ID, lookup and verification of one point hypothesis.

    Parameters
    ----------
    pts : numpy.ndarray
        ``(k, 2)`` points (image pixels).
    lines : SideLines
        ``lines[i]``: the triangle side lines through point ``i`` (unit normals, offsets).
    corners : numpy.ndarray
        ``(4, 2)`` refined data-area corners (image pixels).
    quad : Quad
        The candidate.
    catalogue : Catalogue
        Lookup, its point counts and the settings.
    clock : StageClock
        Charged with ``"identify"`` and ``"verify"`` time.

    Returns
    -------
    Detection or Rejection
        Rejections ``"point_count"``, ``"general_position"``, ``"low_margin"``,
        ``"unknown_id"``, ``"polarity_not_in_dictionary"`` or those of
        :func:`~ottag_db.decode.verify.verify`.
    """
    p = catalogue.params
    k = len(pts)
    if k < 3 or k > 8 or (k not in catalogue.ks and not p.allow_unknown):
        return Rejection("point_count", f"{k} points")
    table, orderings = read_set(pts)
    if not table.margin > 0:
        return Rejection("general_position")
    best_mat = orderings[0][1]
    lam = lambda_text(best_mat)
    if table.margin < p.min_margin_px:
        low = Rejection("low_margin", f"margin {table.margin:.2f} px", lam)
        return _disambiguate(pts, lines, corners, quad, table.margin, low, catalogue, clock) if p.verify else low
    minimal = _minimal(orderings)
    entry = catalogue.lookup.get(lam)
    if entry is None:
        if not p.allow_unknown:
            return Rejection("unknown_id", "", lam)
        return Detection(
            lam, k, None, None, quad.polarity, pts[list(minimal[0])], None,
            corners, None, None, table.margin,
        )  # fmt: skip
    member = _for_polarity(entry, quad.polarity, lam)
    if isinstance(member, Rejection):
        return member
    clock.lap("identify")
    result = verify(member, pts, lines, minimal, corners, quad, table.margin, lam, p)
    clock.lap("verify")
    return result


def _minimal(orderings: list[tuple[tuple[int, ...], NDArray[np.int8]]]) -> list[tuple[int, ...]]:
    """The labelings of ``orderings`` (smallest first) that reach the smallest λ."""
    best_key = orderings[0][1].tobytes()
    return [lab for lab, mat in orderings if mat.tobytes() == best_key]


def _for_polarity(entry: LookupEntry, polarity: Polarity, lam: str) -> LookupEntry | Rejection:
    """``entry`` with the tag number of ``polarity`` when it is a dictionary member (its
    ``extra["tags"]`` maps polarity → number), or the rejection when the member does not
    exist in that polarity."""
    tags = entry.extra.get("tags") if entry.extra else None
    if not isinstance(tags, Mapping):
        return entry
    number = tags.get(polarity)
    if number is None:
        return Rejection("polarity_not_in_dictionary", f"member only as {'/'.join(sorted(tags))}", lam)
    return replace(entry, tag=int(number))


def _disambiguate(
    pts: _F64,
    lines: SideLines,
    corners: _F64,
    quad: Quad,
    low_margin: float,
    low: Rejection,
    catalogue: Catalogue,
    clock: StageClock,
) -> Detection | Rejection:
    """A reading with one point nearly on the line through two others: read both sides.

    The point is put on either side of the line (at ``min_margin_px``); each reading is
    looked up and verified on the same side lines. Exactly one must verify, and the
    realization it maps into the image must itself keep ``min_margin_px``; else ``low``.
    """
    p = catalogue.params
    table = orientation_table(pts)
    first, second = table.pairs.first, table.pairs.second
    dist = table.distance
    rows, cols = np.nonzero(dist < p.min_margin_px)
    near = {tuple(sorted((int(first[u]), int(second[u]), int(v)))) for u, v in zip(rows, cols, strict=True)}
    if len(near) != 1:
        return low  # more than one near-collinear triple: too many readings
    r, pt = np.unravel_index(int(np.argmin(dist)), dist.shape)
    d = pts[second[r]] - pts[first[r]]
    nrm = np.array([-d[1], d[0]]) / np.maximum(np.hypot(d[0], d[1]), 1e-12)
    s = float(nrm @ (pts[pt] - pts[first[r]]))
    found: list[Detection] = []
    for side in (1.0, -1.0):
        moved = pts.copy()
        moved[pt] += (side * p.min_margin_px - s) * nrm
        moved_table, orderings = read_set(moved)
        if not moved_table.margin > 0:
            return low
        lam = lambda_text(orderings[0][1])
        entry = catalogue.lookup.get(lam)
        if entry is None:
            continue
        member = _for_polarity(entry, quad.polarity, lam)
        if isinstance(member, Rejection):
            continue
        clock.lap("identify")
        res = verify(member, pts, lines, _minimal(orderings), corners, quad, low_margin, lam, p)
        clock.lap("verify")
        if isinstance(res, Detection) and res.homography is not None and res.model_points is not None:
            if margin(apply_homography(res.homography, res.model_points)) >= p.min_margin_px:
                found.append(res)
        elif isinstance(res, Detection):
            return low  # verified without a realization to check: undecided
    return found[0] if len(found) == 1 else low
