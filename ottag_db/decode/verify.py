"""Verification stage: map every stored realization onto the detected points by a homography."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.lookup import LookupEntry
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.placement_check import (
    PLACEMENT_BOUND_FACTOR,
    PLACEMENT_MAX_UNITS,
    PlacementError,
    apply_homography,
    placement_error,
    printed_corners,
)
from ottag_db.decode.quads import shows_print
from ottag_db.decode.types import Detection, Quad, Rejection

__all__ = [
    "Assessment",
    "LineSystem",
    "Model",
    "SideLines",
    "apply_homography",
    "assess",
    "homography_from_lines",
    "line_system",
    "map_corners_back",
    "model",
    "tag_plane_corner_order",
    "verify",
]

_F64 = NDArray[np.float64]

#: The side lines through each point of a hypothesis: ``(normals (m, 2), offsets (m,))``
#: per point, n·x = c, image pixels.
SideLines = Sequence[tuple[_F64, _F64]]


@dataclass(frozen=True)
class LineSystem:
    """The side lines of one point hypothesis, stacked and normalised once for every
    (realization, labeling) fit: unit normals ``nrm``, offsets ``off`` (n·x = c), the input
    index of each line's point ``owner``, the lines in normalised homogeneous form ``lh`` and
    the de-normalising map ``ti_inv``."""

    nrm: _F64
    off: _F64
    owner: NDArray[np.intp]
    lh: _F64
    ti_inv: _F64


#: The rejection detail of a reading whose side lines are too few to fit a homography.
_UNVERIFIABLE = (
    "a {k}-point reading cannot be verified: its side lines do not fix a homography (8 needed);"
    " decoding without verification (--no-verify, verify=False) reads its order type alone"
)


def line_system(lines: SideLines) -> LineSystem | None:
    """Stack and normalise the side lines of a hypothesis.

    Parameters
    ----------
    lines : sequence
        ``lines[i]``: the side lines through point ``i`` (see :data:`SideLines`).

    Returns
    -------
    LineSystem or None
        None with fewer than 8 lines (a homography has 8 degrees of freedom).
    """
    nrm = np.concatenate([n for n, _ in lines])
    off = np.concatenate([c for _, c in lines])
    owner = np.repeat(np.arange(len(lines)), [len(c) for _, c in lines])
    if len(off) < 8:
        return None
    # image lines normalised like their points: the feet of the lines to zero mean / unit spread
    foot = nrm * off[:, None]
    ic = foot.mean(axis=0)
    df = foot - ic
    isc = math.sqrt(2.0) / max(float(np.sqrt((df * df).sum(axis=1)).mean()), 1e-12)
    # a line (n, c) is the homogeneous vector (n_x, n_y, -c); lines map by ti^-T, where
    # ti^-1 = [[1/isc, 0, ic_x], [0, 1/isc, ic_y], [0, 0, 1]]
    lh = np.empty((len(off), 3))
    lh[:, :2] = nrm / isc
    lh[:, 2] = nrm @ ic - off
    lh /= np.maximum(np.hypot(lh[:, 0], lh[:, 1]), 1e-12)[:, None]
    ti_inv = np.array([[1.0 / isc, 0, ic[0]], [0, 1.0 / isc, ic[1]], [0, 0, 1.0]])
    return LineSystem(nrm, off, owner, lh, ti_inv)


@dataclass(frozen=True)
class Model:
    """A stored realization for the homography fit: its points ``(k, 2)`` (tag-plane units),
    the points normalised to zero mean and mean distance √2 in homogeneous form ``xs``
    ``(k, 3)``, and the normalising map ``tm`` (3 × 3)."""

    points: _F64
    xs: _F64
    tm: _F64


def model(src: _F64) -> Model:
    """Normalise one realization ``(k, 2)`` for :func:`homography_from_lines`."""
    mc = src.mean(axis=0)
    dm = src - mc
    ms = math.sqrt(2.0) / max(float(np.sqrt((dm * dm).sum(axis=1)).mean()), 1e-12)
    xs = np.empty((len(src), 3))
    xs[:, :2] = dm * ms
    xs[:, 2] = 1.0
    tm = np.array([[ms, 0, -ms * mc[0]], [0, ms, -ms * mc[1]], [0, 0, 1.0]])
    return Model(src, xs, tm)


def homography_from_lines(mdl: Model, system: LineSystem, rep: NDArray[np.intp]) -> _F64 | None:
    """Homography mapping each model point onto the side lines through its detected point.

    Linear least squares (normalised DLT) on the incidences ``l·H·x = 0`` of every model point
    ``x`` with every image line ``l`` fitted through the detected point; a vertex is thus
    constrained across each of its sides, where it is measured well, and not along the axis
    of a sharp tip, where the side lines meet at a small angle.

    Parameters
    ----------
    mdl : Model
        The normalised realization.
    system : LineSystem
        The normalised side lines.
    rep : numpy.ndarray
        ``rep[l]``: index in ``mdl.points`` of the model point of line ``l``.

    Returns
    -------
    numpy.ndarray or None
        ``(3, 3)`` tag plane → image, ``H[2, 2] = 1``; None when the system is degenerate.
    """
    lh = system.lh
    a = (lh[:, :, None] * mdl.xs[rep][:, None, :]).reshape(len(lh), 9)
    try:
        # the least-squares null vector: eigenvector of the smallest eigenvalue of AᵀA (9 × 9;
        # cheaper than the SVD of A, and the normalisation keeps AᵀA well conditioned)
        _, vecs = np.linalg.eigh(a.T @ a)
    except np.linalg.LinAlgError:
        return None
    hmat = system.ti_inv @ vecs[:, 0].reshape(3, 3) @ mdl.tm
    if not np.isfinite(hmat).all() or abs(hmat[2, 2]) < 1e-12:
        return None
    out: _F64 = hmat / hmat[2, 2]
    return out


def map_corners_back(hmat: _F64, corners: _F64) -> list[list[float]] | None:
    """The 4 image ``corners`` mapped to the tag plane by ``hmat``⁻¹.

    Plain Python: a 3 × 3 adjugate and 4 points.

    Returns
    -------
    list or None
        ``[[x, y], …]`` tag-plane corners; None when ``hmat`` is singular or a corner maps to
        infinity.
    """
    (a, b, c), (d, e, f), (g, h, i) = hmat.tolist()
    # adjugate = det · inverse; the scale cancels in the projective division
    inv = (
        (e * i - f * h, c * h - b * i, b * f - c * e),
        (f * g - d * i, a * i - c * g, c * d - a * f),
        (d * h - e * g, b * g - a * h, a * e - b * d),
    )
    det = a * inv[0][0] + b * inv[1][0] + c * inv[2][0]
    if det == 0 or not math.isfinite(det):
        return None
    out: list[list[float]] = []
    for x, y in corners.tolist():
        w = inv[2][0] * x + inv[2][1] * y + inv[2][2]
        if w == 0:
            return None
        out.append([(inv[0][0] * x + inv[0][1] * y + inv[0][2]) / w, (inv[1][0] * x + inv[1][1] * y + inv[1][2]) / w])
    return out


def tag_plane_corner_order(corners: _F64, plane: list[list[float]]) -> _F64:
    """``corners`` reordered tag top-left, top-right, bottom-right, bottom-left.

    Parameters
    ----------
    corners : numpy.ndarray
        ``(4, 2)`` image corners.
    plane : list
        The same corners mapped to the tag plane (x right, y down).

    Returns
    -------
    numpy.ndarray
        ``(4, 2)``; ``corners`` unchanged when a mapped corner is not finite.
    """
    return corners[tag_plane_order(plane)]


def tag_plane_order(plane: list[list[float]]) -> list[int]:
    """The order that puts corners mapped to the tag plane top-left, top-right, bottom-right,
    bottom-left (:func:`tag_plane_corner_order`); ``[0, 1, 2, 3]`` when one is not finite.

    Parameters
    ----------
    plane : list
        ``4 × [x, y]`` corners in the tag plane (x right, y down).

    Returns
    -------
    list of int
    """
    if not all(math.isfinite(v) for xy in plane for v in xy):
        return [0, 1, 2, 3]
    gx = sum(x for x, _ in plane) / 4
    gy = sum(y for _, y in plane) / 4
    ang = [math.atan2(y - gy, x - gx) for x, y in plane]
    # start at the corner seen up-left of the centre in the tag plane (−135°)
    wrapped = [abs(math.remainder(a + 0.75 * math.pi, 2 * math.pi)) for a in ang]
    start = wrapped.index(min(wrapped))
    return sorted(range(4), key=lambda c: (ang[c] - ang[start]) % (2 * math.pi))


@dataclass(frozen=True)
class _Fit:
    """One (realization, labeling) fit: largest point–line error (px), parallelogram error of
    the corners mapped back (rel. to the side), homography, detected points in label order,
    the realization, the corners in the tag plane, the realization mapped to the image, the
    realization's index in the entry and the model point of each side line."""

    err: float
    par: float
    hmat: _F64
    dst: _F64
    src: _F64
    plane: list[list[float]]
    mapped: _F64
    real: int
    rep: NDArray[np.intp]


@dataclass(frozen=True)
class Assessment:
    """The verification of one reading: its ``result`` and the figures soft decoding compares.

    ``error`` (px) is the fit error the reading is judged on: the smallest largest point–line
    distance over its (realization, labeling) fits whose corners map back to a parallelogram
    (any fit without ``check_quad``); ``inf`` when there is none. ``bound`` is the
    reprojection bound of the candidate (px).
    """

    result: Detection | Rejection
    error: float
    bound: float


def verify(
    entry: LookupEntry,
    pts: _F64,
    lines: SideLines,
    minimal: Sequence[tuple[int, ...]],
    corners: _F64,
    quad: Quad,
    margin: float,
    lambda_text: str,
    params: DetectorParams,
    printed: bool = False,
) -> Detection | Rejection:
    """Check a reading against the stored realizations of its order type.

    The :attr:`Assessment.result` of :func:`assess`.
    """
    return assess(entry, pts, lines, minimal, corners, quad, margin, lambda_text, params, printed).result


def assess(
    entry: LookupEntry,
    pts: _F64,
    lines: SideLines,
    minimal: Sequence[tuple[int, ...]],
    corners: _F64,
    quad: Quad,
    margin: float,
    lambda_text: str,
    params: DetectorParams,
    printed: bool = False,
) -> Assessment:
    """Check a reading against the stored realizations of its order type, with its fit error.

    Every (realization, minimal labeling) is mapped onto the points by a homography fitted to
    the side lines; with ``params.verify`` the best fit must stay within the reprojection
    bound, lie where the tag printed its points when the entry knows its placements
    (:mod:`~ottag_db.decode.placement_check`) and (with ``check_quad``) map the data-area
    corners back to a parallelogram.

    Parameters
    ----------
    entry : LookupEntry
        The order type read (``tag`` already that of the detected polarity).
    pts : numpy.ndarray
        ``(k, 2)`` detected points (image pixels, hypothesis order).
    lines : SideLines
        The side lines through each point.
    minimal : list of tuple
        The labelings reaching the minimal λ (``labeling[l]`` = index in ``pts`` of label l).
    corners : numpy.ndarray
        ``(4, 2)`` refined data-area corners (image pixels, clockwise on screen).
    quad : Quad
        The candidate (its area sets the bound, its polarity the detection's).
    margin : float
        Margin of the reading (px).
    lambda_text : str
        The ID read.
    params : DetectorParams
        Uses ``verify``, ``max_reproj_px``/``_rel``, ``check_quad``, ``max_quad_error``.
    printed : bool
        The points must lie where the stored placement prints them at any view, not only at
        oblique or small ones (:func:`~ottag_db.decode.quads.shows_print`).

    Returns
    -------
    Assessment
        The detection, or a ``"verification"`` (fit or printed placement) or
        ``"quad_inconsistent"`` rejection, with the fit error and the bound.
    """
    p = params
    side = math.sqrt(quad.area)
    bound = max(p.max_reproj_px, p.max_reproj_rel * side)
    system = line_system(lines)
    fits = [] if system is None else _fits(entry, pts, system, minimal, corners)
    if not fits:
        if p.verify:
            # (a 3-point tag's points lie on 6 side lines: no homography to verify them with)
            detail = "no realization" if system is not None else _UNVERIFIABLE.format(k=len(lines))
            return Assessment(Rejection("verification", detail, lambda_text), math.inf, bound)
        unverified = Detection(
            lambda_text, entry.k, entry.order_type_id, entry.tag, quad.polarity, pts[list(minimal[0])], None,
            corners, None, None, margin,
        )  # fmt: skip
        return Assessment(unverified, math.inf, bound)
    square = [f for f in fits if f.par <= p.max_quad_error] if p.check_quad else fits
    error = min((f.err for f in square), default=math.inf)
    quad_w = 1.0 if p.check_quad else 0.0
    if p.verify:
        passing = [f for f in fits if f.err <= bound]
        if not passing:
            detail = f"reprojection error {min(f.err for f in fits):.2f} px > {bound:.2f} px"
            return Assessment(Rejection("verification", detail, lambda_text), error, bound)
        # Only at oblique views and on small data areas (where lost vertices fit other order
        # types), or when the caller asks: a tag drawn by another program with its own
        # placement still reads head-on. (There are fits, so system is not None.)
        if (printed or shows_print(quad, p)) and entry.placements and system is not None:
            placed = _placed(entry, passing, system, corners, bound)
            if isinstance(placed, str):
                refusal = Rejection("verification", placed, lambda_text, not_printed=frozenset({lambda_text}))
                return Assessment(refusal, error, bound)
            passing = placed
        elif len(passing) > 1 and entry.placements and system is not None:
            # Head-on the print need not be there, but where it is it tells several fits apart:
            # the labelings of a symmetric order type fit equally well with the tag turned (11 of
            # the 28 symmetric tags of k ≤ 8, head-on at 140 px, read turned without this).
            placed = _placed(entry, passing, system, corners, bound)
            if not isinstance(placed, str):
                passing = placed
        if p.check_quad:
            fits = [f for f in passing if f.par <= p.max_quad_error]
            if not fits:
                detail = f"parallelogram error {min(f.par for f in passing):.3f} of the side"
                return Assessment(Rejection("quad_inconsistent", detail, lambda_text), error, bound)
        else:
            fits = passing
    best = min(fits, key=lambda f: f.err / bound + quad_w * min(f.par, 1e6) / max(p.max_quad_error, 1e-9))
    plc = entry.placements[best.real] if best.real < len(entry.placements) else None
    seen = None
    measured = None
    if plc is not None:  # a corner the print puts elsewhere is hidden: it takes the printed position
        shown = p.verify and (printed or shows_print(quad, p))  # layout and placement were checked
        as_measured = corners
        corners, seen_array = printed_corners(plc, best.hmat, corners, bound, shown, (best.src, best.dst))
        seen = tuple(bool(v) for v in seen_array[tag_plane_order(best.plane)])
        if not all(seen):  # in file coordinates, which follow the homography when the detection is moved
            measured = _to_file(best.hmat, tag_plane_corner_order(as_measured, best.plane))
    detection = Detection(
        lambda_text=lambda_text,
        k=entry.k,
        order_type_id=entry.order_type_id,
        tag=entry.tag,
        polarity=quad.polarity,
        points=best.dst.copy(),
        model_points=best.src.copy() if entry.unique_min else None,
        corners=tag_plane_corner_order(corners, best.plane),
        homography=best.hmat,
        reprojection_error_px=float(np.sqrt(((best.mapped - best.dst) ** 2).sum(axis=1)).max()),
        margin_px=margin,
        corners_seen=seen,
        corners_measured=measured,
    )
    return Assessment(detection, error, bound)


def _to_file(hmat: _F64, pts: _F64) -> _F64 | None:
    """Image points mapped back through a homography (file coordinates → image); None when it
    is singular or a point maps to infinity."""
    try:
        out = apply_homography(np.asarray(np.linalg.inv(hmat), dtype=np.float64), pts)
    except np.linalg.LinAlgError:
        return None
    return out if np.isfinite(out).all() else None


def _placed(entry: LookupEntry, fits: list[_Fit], system: LineSystem, corners: _F64, bound: float) -> list[_Fit] | str:
    """The fits whose reading agrees with the stored placement (see
    :data:`PLACEMENT_BOUND_FACTOR`; the corners in the tag order of the fit), or why none
    does. A fit of a realization without a known placement is kept."""
    kept: list[_Fit] = []
    closest = PlacementError(math.inf, math.inf)
    for f in fits:
        plc = entry.placements[f.real] if f.real < len(entry.placements) else None
        if plc is None:
            kept.append(f)
            continue
        e = placement_error(
            plc, f.src, f.dst, (system.nrm, system.off), f.rep, tag_plane_corner_order(corners, f.plane)
        )
        if e.image_px <= PLACEMENT_BOUND_FACTOR * bound or e.plane <= PLACEMENT_MAX_UNITS:
            kept.append(f)
        elif e.image_px < closest.image_px:
            closest = e
    if kept:
        return kept
    return (
        f"points {closest.image_px:.2f} px (> {PLACEMENT_BOUND_FACTOR * bound:.2f}) and "
        f"{closest.plane:.2f} of the side (> {PLACEMENT_MAX_UNITS}) from the printed placement"
    )


def _fits(
    entry: LookupEntry, pts: _F64, system: LineSystem, minimal: Sequence[tuple[int, ...]], corners: _F64
) -> list[_Fit]:
    """Every (realization, minimal labeling) fit whose homography maps the realization and the
    corners back to finite points."""
    fits: list[_Fit] = []
    k = len(pts)
    for index, real in enumerate(entry.realizations):
        src = np.asarray(real, dtype=np.float64)
        if src.shape != pts.shape:
            continue
        mdl = model(src)
        for lab in minimal:
            dst = pts[list(lab)]
            model_of = [0] * k  # detected point index → model point index
            for label, point in enumerate(lab):
                model_of[point] = label
            rep = np.asarray(model_of)[system.owner]
            hmat = homography_from_lines(mdl, system, rep)
            if hmat is None:
                continue
            mapped = apply_homography(hmat, src)
            if not np.isfinite(mapped).all():
                continue
            err = float(np.abs((system.nrm * mapped[rep]).sum(axis=1) - system.off).max())
            g = map_corners_back(hmat, corners)
            if g is None:
                continue
            (g0x, g0y), (g1x, g1y), (g2x, g2y), (g3x, g3y) = g
            sides = 0.25 * (
                math.hypot(g1x - g0x, g1y - g0y) + math.hypot(g2x - g1x, g2y - g1y)
                + math.hypot(g3x - g2x, g3y - g2y) + math.hypot(g0x - g3x, g0y - g3y)
            )  # fmt: skip
            par = math.hypot(g0x - g1x + g2x - g3x, g0y - g1y + g2y - g3y) / max(sides, 1e-9)
            if not math.isfinite(par):
                par = math.inf
            fits.append(_Fit(err, par, hmat, dst, src, g, mapped, index, rep))
    return fits
