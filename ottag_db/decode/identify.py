"""Identification stage: a point hypothesis → canonical ID → lookup entry → verification."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import lambda_text
from ottag_db.core.layout import LAYOUT_MAX_K
from ottag_db.core.lookup import LookupEntry, TagLookup
from ottag_db.core.single_set import OrientationTable, read_set
from ottag_db.core.types import Polarity
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.profile import StageClock
from ottag_db.decode.quads import shows_print, thinnest_side
from ottag_db.decode.soft import (
    FlipReading,
    Scored,
    ambiguous_triples,
    choose,
    confirms,
    flip_readings,
    layout_matches,
    observed_triangles,
)
from ottag_db.decode.types import Detection, Quad, Rejection
from ottag_db.decode.verify import Assessment, SideLines, assess, verify

__all__ = ["PRINT_MIN_SEEN_CORNERS", "Catalogue", "for_polarity", "identify"]

_F64 = NDArray[np.float64]

#: A reading that showed its print (stored layout and placement) on a data area with pixels
#: across it (at least ``print_check_side_px`` across its thinnest direction, where corners
#: are measured to a fraction of the bound) must also have at least this many of its measured
#: corners where the print puts them. A finger over a corner or a frame cutting one leaves
#: three; a tag that lost a whole triangle, read as a type of fewer points whose layout is the
#: triangles left, passed the loose placement check with all four corners far from its print
#: (a drawing by another program at 70°, 150 px across). Below that width corners at grazing
#: views miss the print by more than the bound even on correct readings (1 of 415 had none).
PRINT_MIN_SEEN_CORNERS = 2


@dataclass(frozen=True)
class Catalogue:
    """What identification reads besides the points: the ``lookup``, the point counts ``ks`` it
    holds (taken once, the lookup is fixed for a detector's life) and the ``params``."""

    lookup: TagLookup
    ks: frozenset[int]
    params: DetectorParams


def identify(
    pts: _F64,
    lines: SideLines,
    corners: _F64,
    quad: Quad,
    catalogue: Catalogue,
    clock: StageClock,
    print_required: frozenset[str] = frozenset(),
    occluded: bool = False,
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
    print_required : frozenset of str, optional
        IDs that must show their tag as printed (layout and placement) at any view: those an
        earlier reading of the same data area was refused as not printed.
    occluded : bool, optional
        Something crossed the data area's border (:attr:`~ottag_db.decode.types.DataArea.intrusions`):
        whatever the ID, the tag must show its print at any view (so must a quad whose corners
        were inferred, :attr:`~ottag_db.decode.types.Quad.inferred`, unless only the frame's
        edge cut it, :attr:`~ottag_db.decode.types.Quad.frame_cut`).

    Returns
    -------
    Detection or Rejection
        Rejections ``"point_count"``, ``"general_position"``, ``"low_margin"``,
        ``"unknown_id"``, ``"polarity_not_in_dictionary"`` or those of
        :func:`~ottag_db.decode.verify.verify`. A reading under ``min_margin_px`` is
        soft-decoded (with ``verify`` and ``soft_max_flips`` > 0): a detection then has
        ``corrected_flips`` set, a refusal is ``"low_margin"`` with the reason in its detail.
        The detected triangles must be the ID's printed layout (when the lookup knows it) at
        oblique or small views (:func:`~ottag_db.decode.quads.shows_print`), and also
        when the verified points lie farther than the reprojection bound from where the fit
        puts them (they fit only along their side lines); the points must then also lie where
        the stored placement prints them.
    """
    p = catalogue.params
    occluded = occluded or (quad.inferred and not quad.frame_cut)
    k = len(pts)
    if k < 3 or k > LAYOUT_MAX_K or (k not in catalogue.ks and not p.allow_unknown):
        return Rejection("point_count", f"{k} points")
    table, orderings = read_set(pts)
    if not table.margin > 0:
        return Rejection("general_position")
    best_mat = orderings[0][1]
    lam = lambda_text(best_mat)
    if table.margin < p.min_margin_px:
        low = Rejection("low_margin", f"margin {table.margin:.2f} px", lam)
        if not p.verify or p.soft_max_flips == 0 or occluded:  # (soft decoding needs every triangle)
            return low
        return _soft_decode(pts, lines, corners, quad, table, low, catalogue, clock)
    minimal = _minimal(orderings)
    entry = catalogue.lookup.get(lam)
    if entry is None:
        if not p.allow_unknown or occluded:  # (an occluded tag must show its print: unknown has none)
            return Rejection("unknown_id", "", lam)
        return Detection(
            lam, k, None, None, quad.polarity, pts[list(minimal[0])], None,
            corners, None, None, table.margin,
        )  # fmt: skip
    member = for_polarity(entry, quad.polarity, lam)
    if isinstance(member, Rejection):
        return member
    required = occluded or lam in print_required
    # Without verification the order type alone decides (the paper's rule): a tag drawn with
    # other triangles or margins reads at any view, so the print is never required.
    printed_only = p.verify and member.layouts and (required or shows_print(quad, p))
    if printed_only:
        printed = _as_printed(member, minimal, observed_triangles(lines))
        if printed is None:
            view = "occluded" if occluded else "refused as not printed before" if required else "oblique or small view"
            detail = f"{view}: the detected triangles are not this tag's layout"
            return Rejection("verification", detail, lam, not_printed=frozenset({lam}))
        member, minimal = printed
    turned: tuple[LookupEntry, list[tuple[int, ...]]] | None = None
    if not printed_only and member.layouts and len(minimal) > 1:
        # A symmetric order type: its labelings read the same ID with the tag turned. Head-on
        # the print need not be there (tags drawn by other programs), but where its triangles
        # are they tell the labelings apart (the placement, in verification, too). Another
        # program's triangles can match the stored layout under a wrong turn: the labelings
        # they pick must then fit, their points too (a turn of a near-symmetric point set fits
        # the side lines within the bound with its points a dozen px off), else every labeling
        # is judged by its fit. Only the labeling changes: the order type read is the same.
        printed = _as_printed(member, minimal, observed_triangles(lines))
        if printed is not None:
            turned, (member, minimal) = (member, minimal), printed
    clock.lap("identify")
    checked = assess(member, pts, lines, minimal, corners, quad, table.margin, lam, p, printed=required)
    if turned is not None and not _points_within(checked):
        again = assess(turned[0], pts, lines, turned[1], corners, quad, table.margin, lam, p, printed=required)
        if _points_within(again) or not isinstance(checked.result, Detection):
            (member, minimal), checked = turned, again
    result = checked.result
    if (
        isinstance(result, Detection)
        and p.verify
        and member.layouts
        and not printed_only
        and result.reprojection_error_px is not None
        and result.reprojection_error_px > checked.bound
    ):
        # The points fit the lines through them but lie farther than the bound from where the
        # fit puts them (ill-conditioned vertices, e.g. a sliver tip): how a tag that lost a
        # vertex also reads as a type of fewer points. Such a reading must show that type as
        # printed, layout and placement, as at oblique views (8-point tags at 43° and 53° read
        # as 7-point types).
        printed = _as_printed(member, minimal, observed_triangles(lines))
        if printed is None:
            detail = (
                f"points {result.reprojection_error_px:.2f} px off the fit (bound {checked.bound:.2f} px):"
                " the detected triangles are not this tag's layout"
            )
            result = Rejection("verification", detail, lam, not_printed=frozenset({lam}))
        else:
            member, minimal = printed
            result = verify(member, pts, lines, minimal, corners, quad, table.margin, lam, p, printed=True)
            printed_only = True
    if printed_only and isinstance(result, Detection):
        result = _corners_as_printed(result, quad, p)
    clock.lap("verify")
    return result


def _points_within(checked: Assessment) -> bool:
    """Whether the assessment is a detection whose points, not only its side lines, lie within
    its reprojection bound of where its fit puts them."""
    result = checked.result
    return (
        isinstance(result, Detection)
        and result.reprojection_error_px is not None
        and result.reprojection_error_px <= checked.bound
    )


def _corners_as_printed(reading: Detection, quad: Quad, params: DetectorParams) -> Detection | Rejection:
    """A reading that showed its tag as printed, refused when its data area was outlined by its
    contour, keeps ``print_check_side_px`` across its thinnest direction and fewer than
    :data:`PRINT_MIN_SEEN_CORNERS` of its measured corners lie where the print puts them
    (:attr:`~ottag_db.decode.types.Detection.corners_seen`)."""
    seen = reading.corners_seen
    if seen is None or sum(seen) >= PRINT_MIN_SEEN_CORNERS or quad.inferred:
        return reading  # (an outline inferred from the lines of its visible sides measures no corner)
    if thinnest_side(quad) < params.print_check_side_px:
        return reading
    detail = f"{sum(seen)} of the data area's corners where the print puts them"
    return Rejection("verification", detail, reading.lambda_text, not_printed=frozenset({reading.lambda_text}))


def _minimal(orderings: list[tuple[tuple[int, ...], NDArray[np.int8]]]) -> list[tuple[int, ...]]:
    """The labelings of ``orderings`` (smallest first) that reach the smallest λ."""
    best_key = orderings[0][1].tobytes()
    return [lab for lab, mat in orderings if mat.tobytes() == best_key]


def for_polarity(entry: LookupEntry, polarity: Polarity, lam: str) -> LookupEntry | Rejection:
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


def _soft_decode(
    pts: _F64,
    lines: SideLines,
    corners: _F64,
    quad: Quad,
    table: OrientationTable,
    low: Rejection,
    catalogue: Catalogue,
    clock: StageClock,
) -> Detection | Rejection:
    """A reading under ``min_margin_px``: the reading and its ambiguous triples reversed.

    Every candidate of :func:`~ottag_db.decode.soft.flip_readings` that the lookup holds (in
    the detected polarity) and whose flipped chirotope is its stored realization's is
    verified; :func:`~ottag_db.decode.soft.choose` decides. Else ``low``, with why in its
    detail.
    """
    p = catalogue.params
    triples = ambiguous_triples(table, p.min_margin_px)
    if len(triples) > p.soft_max_triples:
        return replace(low, detail=f"{low.detail}; {len(triples)} ambiguous triples")
    observed = observed_triangles(lines)
    found: list[tuple[FlipReading, Assessment]] = []
    for reading in flip_readings(table, triples, p.soft_max_flips):
        entry = catalogue.lookup.get(reading.lambda_text)
        if entry is None:
            continue
        member = for_polarity(entry, quad.polarity, reading.lambda_text)
        if isinstance(member, Rejection) or not member.realizations:
            continue
        if not confirms(pts, reading.flips, reading.minimal[0], member.realizations[0]):
            continue
        printed = _as_printed(member, reading.minimal, observed)
        if printed is None:
            continue  # not the triangles of this order type's tags: not a candidate
        clock.lap("identify")
        found.append(
            (reading, assess(printed[0], pts, lines, printed[1], corners, quad, table.margin, reading.lambda_text, p))
        )
        clock.lap("verify")
    if not found:
        return replace(low, detail=f"{low.detail}; no candidate in the lookup")
    bound = found[0][1].bound
    choice = choose([Scored(isinstance(a.result, Detection), a.error) for _, a in found], bound, p.soft_min_fit_gap)
    if choice.index is None:
        return replace(low, detail=f"{low.detail}; {choice.detail}")
    reading, winner = found[choice.index]
    if not isinstance(winner.result, Detection):  # choose() picks only a candidate that verified
        return low
    return replace(winner.result, corrected_flips=len(reading.flips))


def _as_printed(
    entry: LookupEntry, minimal: Sequence[tuple[int, ...]], observed: frozenset[frozenset[int]] | None
) -> tuple[LookupEntry, list[tuple[int, ...]]] | None:
    """``entry`` with only the realizations, and ``minimal`` with only the labelings, under
    which the detected triangles are a stored layout; None when there are none, or when the
    entry has layouts and the detected triangles are not known. An entry without layouts
    (e.g. a portable dictionary file) is returned whole: its candidates are judged by fit."""
    if not entry.layouts:
        return entry, list(minimal)
    if observed is None:
        return None
    keep = [
        r
        for r, layout in enumerate(entry.layouts)
        if layout and any(layout_matches(observed, layout, lab) for lab in minimal)
    ]
    labs = [lab for lab in minimal if any(layout_matches(observed, entry.layouts[r], lab) for r in keep)]
    if not keep or not labs:
        return None
    kept = replace(
        entry,
        realizations=tuple(entry.realizations[r] for r in keep),
        layouts=tuple(entry.layouts[r] for r in keep),
        placements=tuple(entry.placements[r] for r in keep) if entry.placements else (),
    )
    return kept, labs
