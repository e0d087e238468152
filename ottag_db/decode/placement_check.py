"""The printed-placement check: a reading must lie where its tag printed its points.

A printed tag is its stored realization placed into the data area by its stored affine
placement (:mod:`ottag_db.core.placement`); the refined data-area corners give the homography
from the data area to the image, so each detected point has a printed position that does not
depend on the verification's fit. :func:`~ottag_db.decode.verify.assess` applies it to every
reading whose lookup entry knows its placements (a portable dictionary file does not). It
matters at grazing views, where a tag that lost a triangle can show another order type's
layout and fit its realization by a free homography (issue 13: 8-point tags read as 6-point
types at 82–84°); at milder views correct readings stay far inside it (see
:data:`PLACEMENT_BOUND_FACTOR`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CORNERS_TO_TRUST_PRINT",
    "JOINT_FIT_POINT_SLACK",
    "PLACEMENT_BOUND_FACTOR",
    "PLACEMENT_MAX_UNITS",
    "SEEN_CORNER_WEIGHT",
    "UNIT_SQUARE",
    "PlacementError",
    "apply_homography",
    "data_area_depths",
    "placement_error",
    "printed_corners",
    "square_homography",
]

_F64 = NDArray[np.float64]


def apply_homography(hmat: _F64, pts: _F64) -> _F64:
    """Map ``(n, 2)`` points by a ``(3, 3)`` homography (inf/NaN where a point maps to infinity)."""
    ph = pts @ hmat[:, :2].T + hmat[:, 2]
    w = ph[:, 2:3]
    if w.all():
        out: _F64 = ph[:, :2] / w
        return out
    with np.errstate(divide="ignore", invalid="ignore"):
        out = ph[:, :2] / w
    return out


def data_area_depths(hmat: _F64) -> _F64:
    """The homogeneous depth ``w`` of the data area's corners (:data:`UNIT_SQUARE`) under a
    homography from data-area units: a view of the data area has all four of one sign (its
    points lie between them, ``w`` being linear in the plane); a sign change means the map
    sends part of it across the horizon.

    Parameters
    ----------
    hmat : numpy.ndarray
        ``(3, 3)`` homography data-area units → pixels.

    Returns
    -------
    numpy.ndarray
        ``(4,)`` depths, in the order of :data:`UNIT_SQUARE` (the first is ``hmat[2, 2]``).
    """
    out: _F64 = UNIT_SQUARE @ hmat[2, :2] + hmat[2, 2]
    return out


#: The placement check (:func:`placement_error`) refuses a reading only when it
#: misses the printed placement both ways: in the image by more than this many reprojection
#: bounds across the side lines, and in the data area by more than ``PLACEMENT_MAX_UNITS``.
#: Either alone is not enough. Correct readings at 70–86° (benchmarks/decode_sweeps.py frames,
#: seeds 2018, 7, 11: 360 detections) miss by up to 4.8 bounds in the image (vertices at
#: blurred sliver tips, with the corners fixed, cannot be absorbed by a free homography) and,
#: at 86°, by up to 0.22 of the side in the data area (a pixel across the compressed axis is a
#: large part of it); the 5 wrong readings there (8-point tags that lost a triangle, read as
#: 6-point types showing the same triangles) missed by 2.2–6.6 bounds and 0.26–0.50 of the
#: side. The rule kept 359 of the 360 and refused all 5. At 0–65° (seed 2018, 240 detections)
#: correct readings missed by at most 1.32 bounds and 0.061 of the side.
PLACEMENT_BOUND_FACTOR = 2.0
#: See :data:`PLACEMENT_BOUND_FACTOR`; data-area units (fraction of its side).
PLACEMENT_MAX_UNITS = 0.2

#: The data-area corners in data-area units: top-left, top-right, bottom-right, bottom-left.
UNIT_SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@dataclass(frozen=True)
class PlacementError:
    """How far a reading lies from its tag as printed: ``image_px`` the largest distance (px)
    of a printed point, mapped by the data-area corners, to the side lines through its detected
    point; ``plane`` the largest distance (data-area units) of a detected point, mapped back by
    the corners, to its printed position. ``inf`` when the corners give no homography."""

    image_px: float
    plane: float


def square_homography(corners: _F64) -> _F64 | None:
    """Homography data-area units → image from the 4 corners (unit square ↔ ``corners``).

    Parameters
    ----------
    corners : numpy.ndarray
        ``(4, 2)`` data-area corners (image pixels): tag top-left, top-right, bottom-right,
        bottom-left.

    Returns
    -------
    numpy.ndarray or None
        ``(3, 3)``, ``H[2, 2] = 1``; None when the corners are degenerate.
    """
    a = np.zeros((8, 8))
    for i, ((x, y), (u, v)) in enumerate(zip(UNIT_SQUARE.tolist(), corners.tolist(), strict=True)):
        a[2 * i] = [x, y, 1, 0, 0, 0, -u * x, -u * y]
        a[2 * i + 1] = [0, 0, 0, x, y, 1, -v * x, -v * y]
    try:
        h = np.linalg.solve(a, corners.reshape(8))
    except np.linalg.LinAlgError:
        return None
    return np.append(h, 1.0).reshape(3, 3) if np.isfinite(h).all() else None


def placement_error(
    placement: _F64, src: _F64, dst: _F64, lines: tuple[_F64, _F64], rep: NDArray[np.intp], corners: _F64
) -> PlacementError:
    """How far the detected points are from where the tag printed them.

    A printed tag is its realization placed into the data area by the stored affine
    ``placement``; the refined data-area corners give the homography from the data area to the
    image, so every detected point has a printed position, independent of the fit.

    Parameters
    ----------
    placement : numpy.ndarray
        ``(2, 3)`` affine map of the realization, grid → data-area units.
    src : numpy.ndarray
        ``(k, 2)`` the realization (grid units, canonical label order).
    dst : numpy.ndarray
        ``(k, 2)`` the detected points in the same label order (image pixels).
    lines : tuple of numpy.ndarray
        The side lines of the detected points, stacked: unit normals ``(m, 2)`` and offsets
        ``(m,)`` (n·x = c, image pixels; :class:`~ottag_db.decode.verify.LineSystem`).
    rep : numpy.ndarray
        ``rep[l]``: index in ``src`` of the point of side line ``l`` (the labeling).
    corners : numpy.ndarray
        ``(4, 2)`` data-area corners in tag order (top-left, top-right, bottom-right,
        bottom-left; image pixels).

    Returns
    -------
    PlacementError
        In the image (px, across the side lines, as the fit error) and in the data area.
    """
    hmat = square_homography(corners)
    if hmat is None:
        return PlacementError(math.inf, math.inf)
    placed = src @ placement[:, :2].T + placement[:, 2]
    mapped = apply_homography(hmat, placed)
    try:
        back = apply_homography(np.asarray(np.linalg.inv(hmat), dtype=np.float64), dst)
    except np.linalg.LinAlgError:
        return PlacementError(math.inf, math.inf)
    if not (np.isfinite(mapped).all() and np.isfinite(back).all()):
        return PlacementError(math.inf, math.inf)
    nrm, off = lines
    image_px = float(np.abs((nrm * mapped[rep]).sum(axis=1) - off).max())
    plane = float(np.sqrt(((back - placed) ** 2).sum(axis=1)).max())
    return PlacementError(image_px, plane)


#: Corners that must agree with the printed placement before it is trusted for the others: with
#: three of four where the print puts them, the fourth that is not is hidden (a finger, a
#: frame edge), not a sign of another drawing.
CORNERS_TO_TRUST_PRINT = 3
#: In the fit that gives a hidden corner its printed position (:func:`printed_corners` with
#: ``points``), a seen corner counts as this many points: it is where two sides fitted along
#: their whole edges meet, a point where two triangle sides meet near a tip. Seen corners were
#: measured to 0.03–0.11 % of the side (0.05–0.15 px at 110–170 px) where the points fit their
#: realization to 0.3–0.7 px: about ten times the variance. With equal weights the hidden corners of
#: tags with a corner covered or cut by the frame came up to 2.2 % of the side off the truth
#: (over 160 readings), with ten times the weight up to 1.8 %.
SEEN_CORNER_WEIGHT = 10
#: A corner the points' own fit misplaces by more than the tolerance still counts as seen when a
#: fit of the points and the corners (:data:`SEEN_CORNER_WEIGHT`) holds it within the tolerance
#: and misses no point by more than this many times the larger of the tolerance and the points'
#: own worst miss. Any slack lets the corners bend the fit: at 1.5 a corner measured 10 px off
#: on a strongly foreshortened 150 px data area (points fitted to 0.15 px, tolerance 2.5 px)
#: counted as seen in 17 of 30 draws, at 1.0 in none (tests/decode/test_hidden_corner_fit.py).
#: At 1.0, of 951 readings of tags with a bar, a covered corner or a corner cut by the frame
#: (110–170 px), one whose points fit to 2.2 px kept a corner measured to 0.05 % of the side
#: flagged and placed 3.9 % off; no other corner was more than 1.8 % off.
JOINT_FIT_POINT_SLACK = 1.0


def printed_corners(
    placement: _F64,
    hmat: _F64,
    corners: _F64,
    tolerance_px: float,
    print_shown: bool = False,
    points: tuple[_F64, _F64] | None = None,
) -> tuple[_F64, NDArray[np.bool_]]:
    """The data-area corners where the printed placement puts them, and which were seen there.

    The stored placement maps the realization's plane to data-area units; through the
    homography of a reading (realization plane → image) the data area's corners follow from
    the points alone. A measured corner that agrees within ``tolerance_px`` was seen; when at
    least :data:`CORNERS_TO_TRUST_PRINT` agree, or when the reading showed the print already
    (``print_shown``: its triangles and points are the stored layout and placement), the others
    are hidden or outside the frame and take the printed position. Otherwise (another drawing's
    placement, or no confirmed print) every measured corner stands and counts as seen.

    Parameters
    ----------
    placement : numpy.ndarray
        ``(2, 3)`` affine map, realization plane → data-area units.
    hmat : numpy.ndarray
        ``(3, 3)`` homography, realization plane → image.
    corners : numpy.ndarray
        ``(4, 2)`` measured corners (image pixels, any order).
    tolerance_px : float
        Largest distance of a seen corner from its printed position.
    print_shown : bool, optional
        The reading was checked against the stored layout and placement and passed.
    points : tuple of numpy.ndarray, optional
        The reading's ``(k, 2)`` realization points (plane) and their ``(k, 2)`` image points:
        when a corner is not seen, the seen corners are the most (four, else three) that one
        fit of the points and those corners holds within ``tolerance_px`` (see
        :data:`JOINT_FIT_POINT_SLACK`), and a hidden corner takes its position from that fit
        (the corners, at the data area's extremes, hold the view's perspective better than
        the points inside it).

    Returns
    -------
    corners : numpy.ndarray
        ``(4, 2)`` in the order of ``corners``: measured where seen, printed where not.
    seen : numpy.ndarray
        ``(4,)`` bool.
    """
    affine = np.vstack([placement, [0.0, 0.0, 1.0]])
    try:
        unit_to_image = hmat @ np.linalg.inv(affine)
    except np.linalg.LinAlgError:
        return corners, np.ones(4, dtype=bool)
    printed = apply_homography(unit_to_image, UNIT_SQUARE)
    if not np.isfinite(printed).all():
        return corners, np.ones(4, dtype=bool)
    # each measured corner against the printed one of the same turn (the quad's corner order is
    # its own, and a hidden corner may be far off)
    order = _match_corners(corners, printed)
    matched = printed[order]
    seen = np.linalg.norm(corners - matched, axis=1) <= tolerance_px
    if not print_shown and int(seen.sum()) < CORNERS_TO_TRUST_PRINT:
        return corners, np.ones(4, dtype=bool)
    if points is not None and 0 < int(seen.sum()) < 4:
        plane = apply_homography(np.linalg.inv(affine), UNIT_SQUARE[order])  # each corner's, in the plane
        rms = np.linalg.norm(apply_homography(hmat, points[0]) - points[1], axis=1)
        point_bound = JOINT_FIT_POINT_SLACK * max(tolerance_px, float(rms.max()))
        # the most corners that a fit of the points and those corners holds, each where it
        # was measured (the points' own fit can miss a corner it extrapolates to by more)
        joint: tuple[float, NDArray[np.bool_], _F64] | None = None
        for size in (4, 3):
            for subset in itertools.combinations(range(4), size):
                mask = np.zeros(4, dtype=bool)
                mask[list(subset)] = True
                fitted = _joint_fit(points, plane, corners, mask)
                if fitted is None:
                    continue
                corner_miss = float(np.linalg.norm(fitted[1][mask] - corners[mask], axis=1).max())
                fits = corner_miss <= tolerance_px and fitted[0] <= point_bound
                if fits and (joint is None or corner_miss < joint[0]):
                    joint = (corner_miss, mask, fitted[1])
            if joint is not None:
                break
        if joint is not None:
            seen, matched = joint[1], joint[2]
        else:
            fitted = _joint_fit(points, plane, corners, seen)
            if fitted is not None:
                matched = fitted[1]
    return np.where(seen[:, None], corners, matched), seen


def _joint_fit(
    points: tuple[_F64, _F64], plane: _F64, corners: _F64, seen: NDArray[np.bool_]
) -> tuple[float, _F64] | None:
    """The homography of the points and the ``seen`` corners (weighted by
    :data:`SEEN_CORNER_WEIGHT`): the points' largest miss (px) and where it puts the four
    corners (``plane``: their realization-plane positions); None when it fails."""
    weight = SEEN_CORNER_WEIGHT  # (rows repeated: a weighted least-squares fit)
    src = np.vstack([points[0], np.repeat(plane[seen], weight, axis=0)]).astype(np.float32)
    dst = np.vstack([points[1], np.repeat(corners[seen], weight, axis=0)]).astype(np.float32)
    refit, _ = cv2.findHomography(src, dst, 0)
    if refit is None:
        return None
    hmat = np.asarray(refit, dtype=np.float64)
    placed = apply_homography(hmat, plane)
    mapped = apply_homography(hmat, points[0])
    if not (np.isfinite(placed).all() and np.isfinite(mapped).all()):
        return None
    return float(np.linalg.norm(mapped - points[1], axis=1).max()), placed


#: The cyclic orders of four corners, either direction (a constant index table).
_CYCLIC_ORDERS = np.array(
    [np.roll(base, -r) for base in (np.arange(4), np.arange(4)[::-1]) for r in range(4)], dtype=np.intp
)
_CYCLIC_ORDERS.flags.writeable = False


def _match_corners(corners: _F64, printed: _F64) -> NDArray[np.intp]:
    """For each measured corner the index of its printed corner: the cyclic assignment (either
    direction) of least total distance, which holds when corners are far off."""
    costs = np.linalg.norm(corners[None] - printed[_CYCLIC_ORDERS], axis=2).sum(axis=1)
    best: NDArray[np.intp] = _CYCLIC_ORDERS[int(np.argmin(costs))].copy()
    return best
