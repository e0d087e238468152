"""Order Type Tag decoder: find data areas, fit triangles, read and verify the order type."""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import lambda_orderings, lambda_text
from ottag_db.core.lookup import LookupEntry, TagLookup
from ottag_db.core.types import Polarity
from ottag_db.errors import DecodeError, UsageError

__all__ = [
    "REJECTION_REASONS",
    "Detection",
    "Detector",
    "DetectorParams",
    "Polarity",
    "Rejected",
    "to_gray",
]


#: Reasons a candidate data area can be rejected with (``Rejected.reason``).
REJECTION_REASONS: dict[str, str] = {
    "low_contrast": "the data area holds no two clearly separated grey levels",
    "no_triangles": "no triangle was found inside the data area",
    "touches_border": "a component inside the data area touches its border",
    "non_triangle": "a component inside the data area is not a union of triangles",
    "point_count": "the number of points is outside 3…8 or not held by the lookup",
    "general_position": "three detected points are (numerically) collinear",
    "low_margin": "the smallest point-to-line distance is below min_margin_px",
    "unknown_id": "the order type is not in the lookup",
    "verification": "no stored realization maps onto the points within the reprojection bound",
    "quad_inconsistent": "the data-area corners do not map to a parallelogram of the tag plane",
    "polarity_not_in_dictionary": "the order type is a dictionary member, but not in the detected polarity",
}

_F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Detection:
    """One decoded Order Type Tag in an image.

    Image coordinates are pixels, x = column, y = row, origin at the *centre* of the top-left
    pixel (OpenCV's convention), sub-pixel floats.

    - ``lambda_``: canonical ID ``k:digits``; ``k`` the number of points;
    - ``order_type_id`` / ``tag``: from the lookup entry (None for unknown order types,
      reported only with ``allow_unknown=True``); when the entry's ``extra["tags"]`` maps
      polarity → number (a dictionary lookup), ``tag`` is the number of the detected polarity;
    - ``polarity``: ``"normal"`` (white triangles on a black data area) or ``"inverted"``;
    - ``points``: ``(k, 2)`` detected points, row ``l`` = the point with canonical label ``l``;
    - ``model_points``: ``(k, 2)`` the matched stored realization in canonical order (file/grid
      coordinates), only when the order type has a unique minimal ordering, else None;
    - ``corners``: ``(4, 2)`` sub-pixel data-area corners in the order tag top-left, top-right,
      bottom-right, bottom-left (tag plane, x right, y down), found by mapping the corners
      back through ``homography``; without a homography they are in image clockwise order
      starting at the corner nearest the image origin;
    - ``homography``: ``(3, 3)`` map from the realization's file coordinates (tag plane) to
      the image, normalised so ``H[2, 2] = 1``; None when no realization was available;
    - ``reprojection_error_px``: largest distance between a detected point and its
      realization point mapped by ``homography`` (None without a homography);
    - ``margin_px``: smallest distance from a detected point to a line through two others.
    """

    lambda_: str
    k: int
    order_type_id: int | None
    tag: int | None
    polarity: Polarity
    points: _F64
    model_points: _F64 | None
    corners: _F64
    homography: _F64 | None
    reprojection_error_px: float | None
    margin_px: float

    @property
    def center(self) -> tuple[float, float]:
        """Centre of the data area (mean of the corners), image pixels."""
        c = self.corners.mean(axis=0)
        return float(c[0]), float(c[1])


@dataclass(frozen=True)
class Rejected:
    """A candidate data area that did not become a detection.

    ``reason`` is a key of :data:`REJECTION_REASONS`; ``corners`` the ``(4, 2)`` candidate quad
    (image pixels, clockwise on screen); ``lambda_`` the ID read before the rejection, if any;
    ``detail`` a short human-readable explanation with the measured value.
    """

    reason: str
    polarity: Polarity
    corners: _F64
    lambda_: str | None = None
    detail: str = ""


@dataclass(frozen=True)
class DetectorParams:
    """Decoder settings (lengths in image pixels unless noted).

    Candidate search:

    - ``use_adaptive`` / ``use_otsu``: binarizations searched for data areas: local mean
      thresholding (window ``adaptive_block`` px, odd, 0 = automatic: about 1/16 of the
      shorter image side, at least 15; offset ``adaptive_c`` grey levels), then global Otsu
      for quads the first pass did not give; the Otsu pass runs only when the adaptive pass
      decoded nothing, unless ``otsu_always`` (costs one more contour pass per frame);
    - ``polarities``: which tag polarities to look for;
    - ``min_quad_area_px``: smallest data-area area (px²); ``min_quad_side_px``: shortest side;
    - ``max_candidates``: at most this many candidate quads (largest first) are read per frame.

    Reading:

    - ``min_contrast``: grey levels between the dark and bright class inside the data area;
    - ``min_triangle_area_px``: smaller components inside a data area are ignored as noise;
    - ``merge_radius_px`` / ``merge_radius_rel``: vertex estimates of different triangles are
      one (shared) point when the least-squares intersection of all their side lines lies
      within ``max(merge_radius_px, merge_radius_rel * sqrt(area))`` of each of these lines;
    - ``min_margin_px``: a reading whose smallest point-to-line distance is below this is
      rejected (default 1.0 px: the vertices are fitted to ~0.1–0.3 px, so an orientation
      cannot flip on a margin this large);
    - ``verify``: check the reading against the stored realizations (see :class:`Detector`);
    - ``max_reproj_px`` / ``max_reproj_rel``: reprojection bound
      ``max(max_reproj_px, max_reproj_rel * sqrt(data-area area))`` on the largest distance
      from a mapped realization point to a side line through its detected point (the
      homography is fitted to these point–line incidences, so a sharp tip, well measured
      across its sides but not along its axis, is judged across its sides);
    - ``check_quad`` / ``max_quad_error``: the data-area corners mapped back to the tag plane
      must form a parallelogram: ``|g0 − g1 + g2 − g3|`` at most ``max_quad_error`` times the
      mean side (the tag is placed by an affine map, so the square becomes a parallelogram);
    - ``allow_unknown``: also report order types missing from the lookup (IDs without
      ``order_type_id``; with ``verify`` they cannot be verified and are reported unverified).
    """

    use_otsu: bool = True
    use_adaptive: bool = True
    otsu_always: bool = False
    adaptive_block: int = 0
    adaptive_c: float = 7.0
    polarities: tuple[Polarity, ...] = ("normal", "inverted")
    min_quad_area_px: float = 400.0
    min_quad_side_px: float = 12.0
    max_candidates: int = 64
    min_contrast: float = 20.0
    min_triangle_area_px: float = 6.0
    merge_radius_px: float = 1.0
    merge_radius_rel: float = 0.006
    min_margin_px: float = 1.0
    verify: bool = True
    max_reproj_px: float = 1.5
    max_reproj_rel: float = 0.02
    check_quad: bool = True
    max_quad_error: float = 0.25
    allow_unknown: bool = False

    def __post_init__(self) -> None:
        if self.adaptive_block and (self.adaptive_block < 3 or self.adaptive_block % 2 == 0):
            raise UsageError(f"adaptive_block must be 0 or an odd number >= 3, got {self.adaptive_block}")
        for p in self.polarities:
            if p not in ("normal", "inverted"):
                raise UsageError(f"unknown polarity {p!r}: use 'normal' and/or 'inverted'")
        if not (self.use_otsu or self.use_adaptive):
            raise UsageError("at least one of use_otsu and use_adaptive must be True")
        for name in ("min_quad_area_px", "min_quad_side_px", "min_margin_px", "max_reproj_px"):
            if float(getattr(self, name)) < 0:
                raise UsageError(f"{name} must not be negative")


def to_gray(image: object) -> NDArray[np.uint8]:
    """Convert an image array to 8-bit grey; raises :class:`DecodeError` for non-images.

    Accepts ``(H, W)``, ``(H, W, 1)``, ``(H, W, 3)`` (BGR) and ``(H, W, 4)`` (BGRA) arrays of
    uint8, uint16 (÷ 257; 12-bit data, maximum < 4096, × 255 / 4095), other integers (shifted
    to 0 and scaled by 255 / range when outside 0…255), bool and floats (``[0, 1]`` scaled to
    255, otherwise clipped to ``[0, 255]``; NaN → 0).
    An empty array gives an empty ``(0, 0)`` result.
    """
    if not isinstance(image, np.ndarray):
        try:
            image = np.asarray(image)
        except Exception as exc:  # pragma: no cover - exotic objects
            raise DecodeError(f"not an image array: {type(image).__name__}") from exc
    arr: NDArray[Any] = image
    if arr.dtype == object or arr.dtype.kind not in "biuf":
        raise DecodeError(f"not an image array: dtype {arr.dtype} (expected integer, bool or float)")
    if arr.size == 0:
        return np.zeros((0, 0), dtype=np.uint8)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (3, 4)):
        raise DecodeError(f"not an image array: shape {arr.shape} (expected (H, W), (H, W, 3) BGR or (H, W, 4) BGRA)")
    if arr.dtype != np.uint8:
        if arr.dtype.kind == "b":
            arr = arr.astype(np.uint8) * 255
        elif arr.dtype.kind == "f":
            f = np.nan_to_num(arr.astype(np.float32), nan=0.0, posinf=255.0, neginf=0.0)
            if f.size and float(f.max()) <= 1.0 and float(f.min()) >= 0.0:
                f = f * 255.0
            arr = np.clip(f + 0.5, 0, 255).astype(np.uint8)
        elif arr.dtype == np.uint16:
            # 16-bit: full range, or 12-bit data (maximum below 4096) scaled from 0…4095
            full = 4095.0 if int(arr.max()) < 4096 else 65535.0
            arr = (arr.astype(np.float32) * (255.0 / full) + 0.5).astype(np.uint8)
        else:
            top = int(arr.max())
            lo = min(int(arr.min()), 0)
            if top > 255 or lo < 0:
                scale = 255.0 / max(top - lo, 1)
                arr = ((arr.astype(np.float32) - lo) * scale + 0.5).astype(np.uint8)
            else:
                arr = arr.astype(np.uint8)
    if arr.ndim == 3:
        code = cv2.COLOR_BGR2GRAY if arr.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        arr = cv2.cvtColor(np.ascontiguousarray(arr), code)
    return np.ascontiguousarray(arr)


@dataclass
class _Quad:
    polarity: Polarity
    corners: _F64  # (4, 2) clockwise on screen
    area: float


@dataclass
class _Triangles:
    """Triangles found in one data area, in ROI coordinates."""

    chains: list[NDArray[np.float64]]  # one (m, 2) contour chain per side, 3 per triangle
    count: int


class Detector:
    """Order Type Tag detector, configured once and applied to many frames.

    Pipeline (paper Sec. 4.1.1–4.1.4, extended): grey → dark masks by global Otsu and by
    local mean thresholding → contours with hierarchy; outer contours of dark regions are
    candidate *normal* data areas, hole contours (bright regions inside dark) candidate
    *inverted* ones; convex quadrilaterals above the area threshold are kept. Inside each
    data area a local Otsu threshold separates the triangles; every component must be a
    union of triangles meeting only at vertices (components that touch themselves at a
    shared vertex are split at the pinch, else by a 3×3 opening as in the paper), and each
    triangle side is re-located at sub-pixel precision on the grey image (threshold
    crossings along the side normals, then a least-squares line); vertices are the
    intersections of adjacent sides, shared vertices are clustered. The canonical ID of the
    points is looked up; with ``verify`` every stored realization and every minimal
    labeling is mapped onto the points by a homography and the best fit must stay within
    the reprojection bound (and the data-area corners must map back to a parallelogram).
    With ``verify=False`` the decision is the paper's: the order type alone.

    When a candidate does not read, the reader tries (in this order, all bounded): alternative
    decompositions (the opening, slit cuts, and *strict* fits that also cut at every reflex
    corner of the polygon approximation and do not let a small triangle hanging at a corner
    pass as part of a large one); the data area upsampled 2× (cubic) for slivers and slits
    about a pixel wide; and, for a reading whose smallest margin is below ``min_margin_px``
    because of exactly one near-collinear triple, both sides of that triple, accepted only
    when exactly one verifies and its mapped realization keeps ``min_margin_px``.
    """

    def __init__(self, lookup: TagLookup, **params: Any):
        names = {f.name for f in fields(DetectorParams)}
        unknown = sorted(set(params) - names)
        if unknown:
            raise UsageError(f"unknown detector parameter(s) {unknown}; valid: {sorted(names)}")
        if "polarities" in params and isinstance(params["polarities"], str):
            params["polarities"] = (params["polarities"],)
        elif "polarities" in params:
            params["polarities"] = tuple(params["polarities"])
        self.params = DetectorParams(**params)
        self.lookup = lookup
        self._ks = frozenset(lookup.ks)
        self.last_rejections: list[Rejected] = []
        self._alternatives = True  # the 2× upsampled re-read tries the plain decompositions only

    @classmethod
    def from_database(cls, path_or_url: str | None = None, dictionary: str | None = None, **params: Any) -> Detector:
        """A detector whose lookup is loaded once from a database (or one named dictionary).

        ``path_or_url`` as ``--db`` (None: ``$OTTAG_DB`` or ``./ottag.sqlite``). The database
        is read here only; :meth:`detect` never touches it. With ``dictionary`` only its
        members decode, and ``Detection.tag`` is the member's number for the detected
        polarity; a member only held in the other polarity is rejected with reason
        ``"polarity_not_in_dictionary"``.
        """
        # Imported here: the decoder core depends on the lookup interface, not on the ORM.
        from ottag_db.store.db import open_database
        from ottag_db.store.dictionaries import dictionary_lookup

        db = open_database(path_or_url)
        try:
            lookup = dictionary_lookup(db, dictionary)
        finally:
            db.close()
        return cls(lookup, **params)

    # ------------------------------------------------------------------ public API
    def detect(self, image: object) -> list[Detection]:
        """Decode all tags in an image; rejected candidates are kept in ``last_rejections``."""
        detections, _ = self.detect_with_rejections(image)
        return detections

    def detect_with_rejections(self, image: object) -> tuple[list[Detection], list[Rejected]]:
        """Decode all tags and also return the rejected candidate data areas with reasons."""
        gray = to_gray(image)
        rejected: list[Rejected] = []
        detections: list[Detection] = []
        if gray.shape[0] < 8 or gray.shape[1] < 8:
            self.last_rejections = rejected
            return detections, rejected
        p = self.params
        passes = (["adaptive"] if p.use_adaptive else []) + (["otsu"] if p.use_otsu else [])
        seen: list[_Quad] = []
        for kind in passes:
            if kind == "otsu" and p.use_adaptive and detections and not p.otsu_always:
                break  # the global threshold is the fallback of the local one
            quads = [q for q in self._candidates(gray, kind) if not any(_same_quad(q, o) for o in seen)]
            seen.extend(quads)
            for quad in sorted(quads, key=lambda q: q.area):
                if _around_detection(quad, detections):
                    continue
                result = self._read(gray, quad)
                if (
                    isinstance(result, Rejected)
                    and result.reason in _RETRY_UPSAMPLED
                    and result.detail != _NO_DECOMPOSITION
                ):
                    result = self._read_upsampled(gray, quad, result)
                if isinstance(result, Rejected):
                    rejected.append(result)
                elif not any(_same_tag(result, d) for d in detections):
                    detections.append(result)
        self.last_rejections = rejected
        return detections, rejected

    # ------------------------------------------------------------------ candidates
    def _candidates(self, gray: NDArray[np.uint8], kind: str) -> list[_Quad]:
        """Convex quadrilateral contours of one binarization (``"otsu"`` or ``"adaptive"``)."""
        p = self.params
        h, w = gray.shape
        masks: list[NDArray[Any]] = []
        # The automatic local threshold searches the image at half resolution (a quarter of the
        # pixels to threshold and trace) when even the smallest data area keeps sides of
        # ``_HALF_RES_MIN_SIDE`` px there; quads are mapped back (half-res pixel u covers image
        # pixels 2u, 2u + 1: centre 2u + 0.5) and their sides are refined on the full image.
        f = 1
        if kind == "otsu":
            _, m = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
            masks.append(m)
        else:
            block = p.adaptive_block or max(15, (min(h, w) // 16) | 1)
            src: NDArray[Any] = gray
            if not p.adaptive_block and min(h, w) >= 240 and p.min_quad_side_px >= 2 * _HALF_RES_MIN_SIDE:
                f = 2
                src = cv2.resize(gray, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
                block = max(7, (block // 2) | 1)
            masks.append(
                cv2.adaptiveThreshold(src, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block, p.adaptive_c)
            )
        want_normal = "normal" in p.polarities
        want_inverted = "inverted" in p.polarities
        min_len = 4 * p.min_quad_side_px / f
        min_area = max(p.min_quad_area_px, p.min_quad_side_px**2)
        max_area = 0.95 * h * w
        quads: list[_Quad] = []
        for m in masks:
            contours, hier = cv2.findContours(m, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
            if hier is None:
                continue
            parents = hier[0][:, 3]
            for i, c in enumerate(contours):
                if len(c) < min_len:
                    continue
                inverted = bool(parents[i] >= 0)
                if (inverted and not want_inverted) or (not inverted and not want_normal):
                    continue
                approx = cv2.approxPolyDP(c, 0.03 * len(c), True)
                if len(approx) != 4:
                    # a steep view makes a thin quad whose short sides fall within 3 % of the
                    # perimeter of the long ones
                    approx = cv2.approxPolyDP(c, 0.012 * len(c), True)
                if len(approx) != 4 or not cv2.isContourConvex(approx):
                    continue
                q = approx.reshape(4, 2).astype(np.float64)
                if f != 1:
                    q = q * f + 0.5 * (f - 1)
                    approx = q.astype(np.float32).reshape(4, 1, 2)
                area = abs(float(cv2.contourArea(approx)))
                if area < min_area or area > max_area:
                    continue
                if q[:, 0].min() < 2 or q[:, 1].min() < 2 or q[:, 0].max() > w - 3 or q[:, 1].max() > h - 3:
                    continue
                (ax, ay), (bx, by), (cx, cy), (dx, dy) = q.tolist()
                if min(
                    math.hypot(bx - ax, by - ay), math.hypot(cx - bx, cy - by),
                    math.hypot(dx - cx, dy - cy), math.hypot(ax - dx, ay - dy),
                ) < p.min_quad_side_px:  # fmt: skip
                    continue
                q = _clockwise(q)
                polarity: Polarity = "inverted" if inverted else "normal"
                cand = _Quad(polarity, q, area)
                if not any(_same_quad(cand, o) for o in quads):
                    quads.append(cand)
        quads.sort(key=lambda qq: -qq.area)
        return quads[: p.max_candidates]

    # ------------------------------------------------------------------ reading
    def _read(self, gray: NDArray[np.uint8], quad: _Quad) -> Detection | Rejected:
        p = self.params
        h, w = gray.shape
        q = quad.corners
        x0 = max(math.floor(q[:, 0].min()) - 4, 0)
        y0 = max(math.floor(q[:, 1].min()) - 4, 0)
        x1 = min(math.ceil(q[:, 0].max()) + 5, w)
        y1 = min(math.ceil(q[:, 1].max()) + 5, h)
        roi = gray[y0:y1, x0:x1]
        if quad.polarity == "inverted":
            roi = 255 - roi
        origin = np.array([x0, y0], dtype=np.float64)
        ql = q - origin

        def reject(reason: str, detail: str = "", lam: str | None = None) -> Rejected:
            return Rejected(reason, quad.polarity, q.copy(), lam, detail)

        # Interior mask: the quad without a band along its border (blur of the quiet zone edge).
        side = math.sqrt(quad.area)
        band = max(2, round(0.02 * side))
        mask: NDArray[Any] = np.zeros((roi.shape[0], roi.shape[1]), dtype=np.uint8)
        qi: NDArray[Any] = np.round(ql * 16).astype(np.int32).reshape(4, 1, 2)
        cv2.fillPoly(mask, [qi], 255, cv2.LINE_8, 4)
        cv2.polylines(mask, [qi], True, 0, 2 * band + 1, cv2.LINE_8, 4)
        hist = cv2.calcHist([roi], [0], mask, [256], [0, 256]).ravel()
        thr = _otsu(hist)
        if thr is None or thr[2] - thr[1] < p.min_contrast:
            return reject("low_contrast", "" if thr is None else f"{thr[2] - thr[1]:.0f} grey levels")
        t_mid = 0.5 * (thr[1] + thr[2])
        fg: NDArray[Any] = cv2.bitwise_and(cv2.threshold(roi, t_mid, 255, cv2.THRESH_BINARY)[1], mask)
        frac = cv2.countNonZero(fg) / max(cv2.countNonZero(mask), 1)
        if frac < 0.01 or frac > 0.75:
            return reject("no_triangles", f"bright fraction {frac:.2f}")
        decomps = self._triangles(fg, side, alternatives=False)
        if isinstance(decomps, str):
            # no plain decomposition: try the alternatives (opening, slit cuts) right away
            decomps = self._triangles(fg, side, alternatives=self._alternatives)
            if isinstance(decomps, str):
                return reject(decomps, _NO_DECOMPOSITION if decomps == "non_triangle" else "")
        if not decomps or decomps[0].count == 0:
            return reject("no_triangles")
        if decomps[0].count > _MAX_TRIANGLES:
            return reject("non_triangle", f"{decomps[0].count} triangles")
        roi_f = roi.astype(np.float32)
        tol = max(p.merge_radius_px, p.merge_radius_rel * side)
        sure = max(2 * p.merge_radius_px, 2 * p.merge_radius_rel * side)
        first: Rejected | None = None
        more: Callable[[], list[_Triangles] | str] = (
            (lambda: self._triangles(fg, side, alternatives=True)) if self._alternatives else (lambda: "none")
        )
        corners_l: _F64 | None = None
        corners = q
        for tris in _then_alternatives(decomps, more):
            # Sub-pixel triangle sides on the grey image (with the data-area sides, first time).
            n_t, c_t = _fit_chains(tris.chains)
            verts = _triangle_vertices(n_t, c_t)
            if corners_l is None:
                qn, qc = _lines_through(ql)
                n_all, c_all = _refine_lines(
                    roi_f, np.concatenate([n_t, qn]), np.concatenate([c_t, qc]), verts, t_mid, quad=ql
                )
                st = len(c_t)
                n_t, c_t = n_all[:st], c_all[:st]
                corners_l = _polygon_vertices(n_all[st:], c_all[st:], 4)
                if not np.isfinite(corners_l).all() or np.abs(corners_l - ql).max() > 0.1 * side + 3:
                    corners_l = ql
                corners = corners_l + origin
            else:
                n_t, c_t = _refine_lines(roi_f, n_t, c_t, verts, t_mid)
            verts = _triangle_vertices(n_t, c_t)
            bad = _bad_triangles(verts, corners_l, side)
            if bad:
                if first is None:
                    first = reject("non_triangle", bad)
                continue
            c_img = c_t + n_t @ origin  # side lines in image coordinates
            for pts_l, line_ids in _cluster_hypotheses(verts, n_t, c_t, 0.15 * side, sure, tol):
                lines = [(n_t[ids], c_img[ids]) for ids in line_ids]
                result = self._identify(pts_l + origin, lines, corners, quad)
                if isinstance(result, Detection):
                    return result
                if first is None or first.reason == "non_triangle":
                    first = result
        return first if first is not None else reject("non_triangle", "degenerate vertex")

    def _read_upsampled(self, gray: NDArray[np.uint8], quad: _Quad, first: Rejected) -> Detection | Rejected:
        """Read a candidate again on its data area upsampled 2× (cubic), for slivers and slits
        about a pixel wide that the binary mask at the image's own scale merges or loses.

        Lengths in the parameters are scaled with the image, except ``min_margin_px`` and the
        reprojection floor, which keep their meaning in image pixels (checked after mapping the
        reading back). Returns ``first`` when this reading fails too.
        """
        side = math.sqrt(quad.area)
        if side > _UPSAMPLE_MAX_SIDE:
            return first
        h, w = gray.shape
        q = quad.corners
        x0 = max(math.floor(q[:, 0].min()) - 6, 0)
        y0 = max(math.floor(q[:, 1].min()) - 6, 0)
        x1 = min(math.ceil(q[:, 0].max()) + 7, w)
        y1 = min(math.ceil(q[:, 1].max()) + 7, h)
        f = 2.0
        up: NDArray[np.uint8] = np.asarray(
            cv2.resize(gray[y0:y1, x0:x1], None, fx=f, fy=f, interpolation=cv2.INTER_CUBIC), dtype=np.uint8
        )
        # pixel centres: up pixel u lies at x = x0 + (u + 0.5) / f − 0.5 of the image
        shift = np.array([x0 + 0.5 / f - 0.5, y0 + 0.5 / f - 0.5])
        sub = self._upsampled_detector(f)
        res = sub._read(up, _Quad(quad.polarity, (q - shift) * f, quad.area * f * f))
        if not isinstance(res, Detection):
            return first
        margin = res.margin_px / f
        if margin < self.params.min_margin_px:
            return first
        to_img = np.array([[1 / f, 0, shift[0]], [0, 1 / f, shift[1]], [0, 0, 1.0]])
        hom = None if res.homography is None else to_img @ res.homography
        if hom is not None:
            hom = hom / hom[2, 2]
        return replace(
            res,
            points=res.points / f + shift,
            corners=res.corners / f + shift,
            homography=hom,
            reprojection_error_px=None if res.reprojection_error_px is None else res.reprojection_error_px / f,
            margin_px=margin,
        )

    def _upsampled_detector(self, f: float) -> Detector:
        sub = self.__dict__.get("_up_detector")
        if sub is None:
            p = self.params
            sub = Detector(
                self.lookup,
                **{
                    **{fl.name: getattr(p, fl.name) for fl in fields(DetectorParams)},
                    "min_quad_area_px": p.min_quad_area_px * f * f,
                    "min_quad_side_px": p.min_quad_side_px * f,
                    "min_triangle_area_px": p.min_triangle_area_px * f * f,
                    "merge_radius_px": p.merge_radius_px * f,
                    "min_margin_px": p.min_margin_px * f,
                    "max_reproj_px": p.max_reproj_px * f,
                },
            )
            sub._alternatives = False
            self.__dict__["_up_detector"] = sub
        return sub

    def _realization_models(self, lam: str, entry: LookupEntry) -> list[_Model]:
        """The stored realizations of ``entry``, normalised for the homography fit (cached per
        ID: the lookup is fixed for the detector's life)."""
        cache: dict[str, list[_Model]] = self.__dict__.setdefault("_real_cache", {})
        models = cache.get(lam)
        if models is None:
            models = [_model(np.asarray(real, dtype=np.float64)) for real in entry.realizations]
            cache[lam] = models
        return models

    def _identify(self, pts: _F64, lines: list[tuple[_F64, _F64]], corners: _F64, quad: _Quad) -> Detection | Rejected:
        """ID, lookup and verification of one point hypothesis (image pixels).

        ``lines[i]`` are the side lines (unit normals, offsets: n·x = c) through point i.
        """
        p = self.params
        q = quad.corners

        def reject(reason: str, detail: str = "", lam: str | None = None) -> Rejected:
            return Rejected(reason, quad.polarity, q.copy(), lam, detail)

        k = len(pts)
        if k < 3 or k > 8 or (k not in self._ks and not p.allow_unknown):
            return reject("point_count", f"{k} points")
        margin, orderings = _read_orderings(pts)
        if not margin > 0:
            return reject("general_position")
        best_mat = orderings[0][1]
        lam = lambda_text(best_mat)
        if margin < p.min_margin_px:
            low = reject("low_margin", f"margin {margin:.2f} px", lam)
            return self._disambiguate(pts, lines, corners, quad, margin, low) if p.verify else low
        best_key = best_mat.tobytes()
        minimal = [lab for lab, mat in orderings if mat.tobytes() == best_key]
        entry = self.lookup.get(lam)
        if entry is None:
            if not p.allow_unknown:
                return reject("unknown_id", "", lam)
            return Detection(
                lam, k, None, None, quad.polarity, pts[list(minimal[0])], None,
                corners, None, None, margin,
            )  # fmt: skip
        tags = entry.extra.get("tags") if entry.extra else None
        if isinstance(tags, Mapping):
            # a dictionary member: each of its polarities has its own tag number
            number = tags.get(quad.polarity)
            if number is None:
                return reject("polarity_not_in_dictionary", f"member only as {'/'.join(sorted(tags))}", lam)
            entry = replace(entry, tag=int(number))
        return self._verify(entry, pts, lines, minimal, corners, quad, margin, lam)

    def _disambiguate(
        self, pts: _F64, lines: list[tuple[_F64, _F64]], corners: _F64, quad: _Quad, margin: float, low: Rejected
    ) -> Detection | Rejected:
        """A reading with one point nearly on the line through two others: read both sides.

        The point is put on either side of the line (at ``min_margin_px``); each reading is
        looked up and verified on the same side lines. Exactly one must verify, and the
        realization it maps into the image must itself keep ``min_margin_px``; else ``low``.
        """
        p = self.params
        k = len(pts)
        i, j = np.triu_indices(k, 1)
        d = pts[j] - pts[i]
        ln = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
        cross = d[:, None, 0] * (pts[None, :, 1] - pts[i][:, None, 1]) - d[:, None, 1] * (
            pts[None, :, 0] - pts[i][:, None, 0]
        )
        dist = np.abs(cross) / ln[:, None]
        idx = np.arange(k)
        dist[(idx[None, :] == i[:, None]) | (idx[None, :] == j[:, None])] = np.inf
        rows, cols = np.nonzero(dist < p.min_margin_px)
        near = {tuple(sorted((int(i[u]), int(j[u]), int(v)))) for u, v in zip(rows, cols, strict=True)}
        if len(near) != 1:
            return low  # more than one near-collinear triple: too many readings
        r, pt = np.unravel_index(int(np.argmin(dist)), dist.shape)
        nrm = np.array([-d[r, 1], d[r, 0]]) / ln[r]
        s = float(nrm @ (pts[pt] - pts[i[r]]))
        found: list[Detection] = []
        for side in (1.0, -1.0):
            moved = pts.copy()
            moved[pt] += (side * p.min_margin_px - s) * nrm
            moved_margin, orderings = _read_orderings(moved)
            if moved_margin <= 0:
                return low
            best_mat = orderings[0][1]
            lam = lambda_text(best_mat)
            entry = self.lookup.get(lam)
            if entry is None:
                continue
            tags = entry.extra.get("tags") if entry.extra else None
            if isinstance(tags, Mapping):
                number = tags.get(quad.polarity)
                if number is None:
                    continue
                entry = replace(entry, tag=int(number))
            minimal = [lab for lab, mat in orderings if np.array_equal(mat, best_mat)]
            res = self._verify(entry, pts, lines, minimal, corners, quad, margin, lam)
            if isinstance(res, Detection) and res.homography is not None and res.model_points is not None:
                if _margin(_apply_h(res.homography, res.model_points)) >= p.min_margin_px:
                    found.append(res)
            elif isinstance(res, Detection):
                return low  # verified without a realization to check: undecided
        return found[0] if len(found) == 1 else low

    def _verify(
        self,
        entry: LookupEntry,
        pts: _F64,
        lines: list[tuple[_F64, _F64]],
        minimal: list[tuple[int, ...]],
        corners: _F64,
        quad: _Quad,
        margin: float,
        lam: str,
    ) -> Detection | Rejected:
        p = self.params
        side = math.sqrt(quad.area)
        bound = max(p.max_reproj_px, p.max_reproj_rel * side)
        # every (realization, minimal labeling): homography, largest point error, and how far
        # the corners mapped back to the tag plane are from a parallelogram (rel. to the side)
        fits: list[tuple[float, float, _F64, _F64, _F64, list[list[float]], _F64]] = []
        system = _line_system(lines)
        k = len(pts)
        for model in self._realization_models(lam, entry):
            if system is None:
                break  # fewer than 8 side lines: no homography
            src = model.points
            if src.shape != pts.shape:
                continue
            for lab in minimal:
                dst = pts[list(lab)]
                model_of = [0] * k  # detected point index → model point index
                for label, point in enumerate(lab):
                    model_of[point] = label
                rep = np.asarray(model_of)[system.owner]
                hmat = _homography_lines(model, system, rep)
                if hmat is None:
                    continue
                mapped = _apply_h(hmat, src)
                if not np.isfinite(mapped).all():
                    continue
                err = float(np.abs((system.nrm * mapped[rep]).sum(axis=1) - system.off).max())
                g = _map_corners_back(hmat, corners)
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
                fits.append((err, par, hmat, dst, src, g, mapped))
        if not fits:
            if p.verify:
                return Rejected("verification", quad.polarity, quad.corners.copy(), lam, "no realization")
            return Detection(
                lam, entry.k, entry.order_type_id, entry.tag, quad.polarity, pts[list(minimal[0])], None,
                corners, None, None, margin,
            )  # fmt: skip
        quad_w = 1.0 if p.check_quad else 0.0
        if p.verify:
            passing = [f for f in fits if f[0] <= bound]
            if not passing:
                return Rejected(
                    "verification", quad.polarity, quad.corners.copy(), lam,
                    f"reprojection error {min(f[0] for f in fits):.2f} px > {bound:.2f} px",
                )  # fmt: skip
            if p.check_quad:
                fits = [f for f in passing if f[1] <= p.max_quad_error]
                if not fits:
                    return Rejected(
                        "quad_inconsistent", quad.polarity, quad.corners.copy(), lam,
                        f"parallelogram error {min(f[1] for f in passing):.3f} of the side",
                    )  # fmt: skip
            else:
                fits = passing
        _, _, hmat, dst, src, gl, mapped = min(
            fits, key=lambda f: f[0] / bound + quad_w * min(f[1], 1e6) / max(p.max_quad_error, 1e-9)
        )
        ordered = corners
        if all(math.isfinite(v) for xy in gl for v in xy):
            gx = sum(x for x, _ in gl) / 4
            gy = sum(y for _, y in gl) / 4
            ang = [math.atan2(y - gy, x - gx) for x, y in gl]
            # start at the corner seen up-left of the centre in the tag plane (−135°)
            wrapped = [abs(math.remainder(a + 0.75 * math.pi, 2 * math.pi)) for a in ang]
            start = wrapped.index(min(wrapped))
            order = sorted(range(4), key=lambda c: (ang[c] - ang[start]) % (2 * math.pi))
            ordered = corners[order]
        return Detection(
            lambda_=lam,
            k=entry.k,
            order_type_id=entry.order_type_id,
            tag=entry.tag,
            polarity=quad.polarity,
            points=dst.copy(),
            model_points=src.copy() if entry.unique_min else None,
            corners=ordered,
            homography=hmat,
            reprojection_error_px=float(np.sqrt(((mapped - dst) ** 2).sum(axis=1)).max()),
            margin_px=margin,
        )

    # ------------------------------------------------------------------ triangles
    def _triangles(self, fg: NDArray[Any], side: float, alternatives: bool = True) -> list[_Triangles] | str:
        """Split the bright components of a data area into triangles (contour side chains).

        Returns alternative decompositions, most plausible first (at most
        ``_MAX_DECOMPOSITIONS``): each component's first decomposition by the splitter's
        cuts between concave points, then the 3×3 opening, then slit (notch) cuts; the
        alternatives of one component at a time are combined with the first ones of the others.
        Without ``alternatives`` only the first decomposition (cheap; what almost every tag
        needs); the reader asks for the alternatives when it does not decode.
        """
        p = self.params
        contours, hier = cv2.findContours(fg, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
        if hier is None:
            return [_Triangles([], 0)]
        hh = hier[0]
        min_area = max(p.min_triangle_area_px, 2e-4 * side * side)
        max_area = 0.45 * side * side  # no triangle of a tag covers half its data area
        options: list[list[list[NDArray[np.float64]]]] = []
        budget = [2 * _STRICT_BUDGET]  # strict triangle fits of all components together
        for i, c in enumerate(contours):
            if hh[i][3] >= 0 or len(c) < 8:
                continue
            pts = c.reshape(-1, 2)
            area = abs(float(cv2.contourArea(c)))
            if area + 0.35 * len(pts) < min_area:
                continue
            if area > max_area:
                return "non_triangle"
            if area > 0.1 * side * side:
                # a filled square (e.g. the data area of a nested, inverted tag) is no triangle
                poly = cv2.approxPolyDP(c, 0.03 * len(c), True)
                if len(poly) == 4 and cv2.isContourConvex(poly):
                    return "non_triangle"
            # A ring of triangles (each sharing vertices with the next) encloses a hole: bridge
            # every hole into the outer contour at their closest points (a shared vertex) so
            # the splitter sees one contour pinched at the shared vertices.
            child = hh[i][2]
            while child >= 0:
                hole = contours[child].reshape(-1, 2)
                if len(hole) >= 8:
                    pts = _bridge(pts, hole)
                child = hh[child][0]
            alts = _component_decompositions(
                pts, lambda i=i: _triangles_by_opening(fg, contours, hier, i), alternatives, budget
            )
            if not alts:
                return "non_triangle"
            options.append(alts)
        if not options:
            return [_Triangles([], 0)]
        firsts = [o[0] for o in options]
        out = [_Triangles([ch for f in firsts for ch in f], sum(len(f) for f in firsts) // 3)]
        for ci, alts in enumerate(options):
            for alt in alts[1:]:
                if len(out) >= _MAX_DECOMPOSITIONS:
                    break
                combo = [*firsts[:ci], alt, *firsts[ci + 1 :]]
                out.append(_Triangles([ch for f in combo for ch in f], sum(len(f) for f in combo) // 3))
        return out


# ---------------------------------------------------------------------- helpers
def _clockwise(q: _F64) -> _F64:
    """Order 4 corners clockwise on screen (y down), starting nearest the image origin."""
    pts = q.tolist()
    cx = sum(x for x, _ in pts) / len(pts)
    cy = sum(y for _, y in pts) / len(pts)
    pts.sort(key=lambda xy: math.atan2(xy[1] - cy, xy[0] - cx))
    sums = [x + y for x, y in pts]
    start = sums.index(min(sums))
    return np.array(pts[start:] + pts[:start], dtype=np.float64)


def _around_detection(quad: _Quad, detections: list[Detection]) -> bool:
    """True when ``quad`` is centred on a tag already decoded and not smaller than its data area.

    Candidates are read smallest first, so this skips the outline of a decoded tag's quiet
    zone (or a frame around it) and duplicates of its data area without reading them.
    """
    c = quad.corners.mean(axis=0)
    for d in detections:
        area = abs(float(cv2.contourArea(d.corners.astype(np.float32))))
        if quad.area > 0.8 * area and np.linalg.norm(d.corners.mean(axis=0) - c) < 0.15 * math.sqrt(quad.area):
            return True
    return False


def _same_quad(a: _Quad, b: _Quad) -> bool:
    if a.polarity != b.polarity:
        return False
    ratio = a.area / max(b.area, 1e-9)
    if not 0.7 < ratio < 1.4:
        return False
    d = np.linalg.norm(a.corners.mean(axis=0) - b.corners.mean(axis=0))
    return bool(d < 0.15 * math.sqrt(max(a.area, b.area)))


def _same_tag(a: Detection, b: Detection) -> bool:
    d = np.linalg.norm(a.corners.mean(axis=0) - b.corners.mean(axis=0))
    size = np.linalg.norm(a.corners[0] - a.corners[2])
    return bool(d < 0.2 * size and a.polarity == b.polarity)


def _otsu(hist: NDArray[Any]) -> tuple[int, float, float] | None:
    """Otsu threshold of a 256-bin histogram and the means of the two classes."""
    w0 = np.cumsum(hist, dtype=np.float64)
    total = float(w0[-1])
    if total < 16:
        return None
    s0 = np.cumsum(hist * _LEVELS)
    s_all = float(s0[-1])
    # between-class variance w0·w1·(m0 − m1)² = (total·s0 − s_all·w0)² / (w0·w1)
    num = total * s0 - s_all * w0
    den = w0 * (total - w0)
    between = np.divide(num * num, den, out=np.full(256, -1.0), where=den > 0)
    t = int(np.argmax(between))
    w0t = float(w0[t])
    if w0t <= 0 or total - w0t <= 0:
        return None
    s0t = float(s0[t])
    return t, s0t / w0t, (s_all - s0t) / (total - w0t)


_LEVELS = np.arange(256, dtype=np.float64)


def _triangle_fit(pts: NDArray[Any], strict: float = 0.0) -> list[NDArray[np.float64]] | None:
    """Side chains of a closed contour that is one triangle, or None.

    Corners: the two farthest contour points and the point farthest from their line (paper
    Sec. 4.1.2), then grown to the largest-area triangle of hull points. At most 5 % of the
    contour (without the 10 % next to each corner) may lie farther than ``1 px + 1.5 %`` of
    the side from the line fitted to the side's middle, and the contour area must match the
    triangle's.
    """
    fit = _triangle_fit_parts(pts)
    if fit is None:
        return None
    chains, tri, flat = fit
    if strict and _off_triangle(flat, tri, strict) > max(3, 0.02 * len(flat)):
        return None  # a small triangle hanging at a corner (hidden by the corner trims below)
    return chains


def _triangle_fit_parts(pts: NDArray[Any]) -> tuple[list[NDArray[np.float64]], _F64, _F64] | None:
    """:func:`_triangle_fit` without the strict test: side chains, corners, contour (float)."""
    n = len(pts)
    if n < 8:
        return None
    flat_i = np.ascontiguousarray(pts.reshape(-1, 2), dtype=np.int32)
    c = flat_i.reshape(-1, 1, 2)
    hull = cv2.convexHull(c, returnPoints=False).ravel()
    if len(hull) < 3:
        return None
    flat = flat_i.astype(np.float64)
    hp = flat[hull]
    dd = ((hp[:, None, :] - hp[None, :, :]) ** 2).sum(axis=2)
    ia, ib = divmod(int(np.argmax(dd)), len(hp))
    hpl: list[list[float]] = hp.tolist()
    hrange = range(len(hpl))

    def far_from(p0: list[float], p1: list[float]) -> list[float]:
        """Twice the area of the triangle of each hull point with ``p0`` and ``p1``."""
        ex, ey = p1[0] - p0[0], p1[1] - p0[1]
        return [abs(ex * (y - p0[1]) - ey * (x - p0[0])) for x, y in hpl]

    vals = far_from(hpl[ia], hpl[ib])
    ic = max(hrange, key=vals.__getitem__)  # the first largest, as np.argmax
    sel = [int(ia), int(ib), ic]
    # grow to the largest-area hull triangle (a blunt short side can fool the farthest pair)
    for _ in range(3):
        changed = False
        for r in range(3):
            vals = far_from(hpl[sel[(r + 1) % 3]], hpl[sel[(r + 2) % 3]])
            best = max(hrange, key=vals.__getitem__)
            if best != sel[r] and vals[best] > vals[sel[r]] + 1e-9:
                sel[r] = best
                changed = True
        if not changed:
            break
    idx = sorted({int(hull[s]) for s in sel})
    if len(idx) < 3:
        return None
    tri = flat[idx]
    (t0x, t0y), (t1x, t1y), (t2x, t2y) = tri.tolist()
    t_area = 0.5 * abs((t1x - t0x) * (t2y - t0y) - (t1y - t0y) * (t2x - t0x))
    c_area = abs(float(cv2.contourArea(c)))
    perim = float(cv2.arcLength(c, True))
    if t_area <= 0 or abs(c_area - t_area) > 0.2 * t_area + 0.25 * perim:
        return None
    chains: list[NDArray[np.float64]] = []
    far = 0
    i0, i1, i2 = idx
    for seg in (flat[i0 : i1 + 1], flat[i1 : i2 + 1], np.concatenate([flat[i2:], flat[: i0 + 1]])):
        m = len(seg)
        (sx, sy), (qx, qy) = seg[0].tolist(), seg[-1].tolist()
        ln = math.hypot(qx - sx, qy - sy)
        if ln < 1:
            return None
        if m < 6:
            # a short side (the base of a needle): the chord; the grey-level fit refines it
            chains.append(seg[[0, -1]])
            continue
        trim = max(1, int(0.15 * m))
        core = seg[trim : m - trim]
        # distance of the chain (without its ends) to the line fitted to its core
        t10 = max(1, int(0.1 * m))
        # PCA line of the core from raw moments (pixel coordinates: no loss of precision)
        (sx_, sy_), ((gxx, gxy), (_, gyy)) = core.sum(axis=0).tolist(), (core.T @ core).tolist()
        cx, cy = sx_ / len(core), sy_ / len(core)
        theta = 0.5 * math.atan2(2 * (gxy - sx_ * cy), (gxx - sx_ * cx) - (gyy - sy_ * cy))
        nx, ny = -math.sin(theta), math.cos(theta)
        dist = np.abs(seg[t10 : m - t10] @ np.array((nx, ny)) - (nx * cx + ny * cy))
        far += int(np.count_nonzero(dist > 1.0 + 0.015 * ln))
        chains.append(core)
    if far > max(2, 0.05 * n):
        return None
    return chains, tri, flat


def _off_triangle(pts: _F64, tri: _F64, tol_px: float) -> int:
    """How many contour points lie farther than ``max(tol_px, 0.6 %`` of the longest side) from
    every side segment of the triangle ``tri``."""
    a = tri
    d = tri[_NEXT3] - a
    ln2 = np.maximum((d * d).sum(axis=1), 1e-12)
    rel = pts[:, None, :] - a[None, :, :]  # (n, 3, 2)
    u = np.clip((rel * d[None]).sum(axis=2) / ln2[None], 0.0, 1.0)
    off = rel - u[..., None] * d[None]
    dist2 = (off * off).sum(axis=2).min(axis=1)
    tol = max(tol_px, 0.006 * math.sqrt(float(ln2.max())))
    return int((dist2 > tol * tol).sum())


def _bridge(outer: NDArray[Any], hole: NDArray[Any]) -> NDArray[Any]:
    """One contour running around ``outer`` and, through their closest points, ``hole``."""

    def closest(a: NDArray[Any], b: NDArray[Any]) -> tuple[int, int]:
        d = ((a[:, None, :].astype(np.int64) - b[None, :, :]) ** 2).sum(axis=2)
        i, j = np.unravel_index(int(np.argmin(d)), d.shape)
        return int(i), int(j)

    step = max(1, int(math.sqrt(len(outer) * len(hole) / 4096)))
    i, j = closest(outer[::step], hole[::step])
    i, j = i * step, j * step
    lo_i, lo_j = max(i - step, 0), max(j - step, 0)
    di, dj = closest(outer[lo_i : i + step + 1], hole[lo_j : j + step + 1])
    i, j = lo_i + di, lo_j + dj
    return np.concatenate([outer[: i + 1], hole[j:], hole[: j + 1], outer[i:]])


_MAX_DECOMPOSITIONS = 10
_NEXT4 = np.array([1, 2, 3, 0])
_NEXT3 = np.array([1, 2, 0])
#: The half-resolution candidate search is used only while the smallest data area keeps at
#: least this side (px) there.
_HALF_RES_MIN_SIDE = 6.0
#: Rejections after triangles were found: the reader tries the data area upsampled 2× then.
_RETRY_UPSAMPLED = frozenset(
    {"non_triangle", "point_count", "general_position", "low_margin", "unknown_id", "verification", "quad_inconsistent"}
)
#: Larger data areas (px) are not upsampled (their slivers are wide enough; bounds the cost).
_UPSAMPLE_MAX_SIDE = 640.0
_STRICT_BUDGET = 80
_NO_DECOMPOSITION = "a component is not a union of triangles"
#: More triangles than this cannot hold 8 points (each triangle has 3 of them, two triangles share
#: at most one): the component soup of a non-tag.
_MAX_TRIANGLES = 12


def _then_alternatives(first: list[_Triangles], more: Callable[[], list[_Triangles] | str]) -> Iterator[_Triangles]:
    """``first``, then the decompositions of ``more()`` not already in ``first`` (computed lazily)."""
    yield from first
    if len(first) > 1:
        return  # ``first`` already holds the alternatives
    alts = more()
    if isinstance(alts, str):
        return
    keys = {tuple(np.round(np.concatenate(t.chains)[:, 0]).tolist()) for t in first if t.chains}
    for t in alts:
        if t.chains and tuple(np.round(np.concatenate(t.chains)[:, 0]).tolist()) in keys:
            continue
        yield t


def _component_decompositions(
    pts: NDArray[Any],
    opening: Callable[..., list[NDArray[np.float64]] | None],
    alternatives: bool = True,
    budget: list[int] | None = None,
) -> list[list[NDArray[np.float64]]]:
    """Alternative triangle decompositions of one component contour, most plausible first.

    Without ``alternatives`` only the splitter's first decomposition (or the opening's, if the
    splitter finds none).
    """
    out: list[list[NDArray[np.float64]]] = []
    keys: set[tuple[float, ...]] = set()

    def add(chains: list[NDArray[np.float64]]) -> None:
        if not alternatives:
            out.append(chains)  # the first decomposition only: nothing to deduplicate
            return
        key = tuple(sorted(round(float(v), 0) for ch in chains for v in (ch[0, 0], ch[0, 1])))
        if key not in keys:
            keys.add(key)
            out.append(chains)

    whole = _triangle_fit_parts(pts)
    if whole is not None:
        first: list[NDArray[np.float64]] | None = whole[0]
    else:
        first = next(_split_triangles(pts, 0, False, fitted=True), None)
    if first is not None:
        add(first)
        if not alternatives or (
            whole is not None and _off_triangle(whole[2], whole[1], 1.5) <= max(3, 0.02 * len(whole[2]))
        ):
            return out  # one triangle: nothing to reconsider
    opened = opening()
    if opened is not None:
        add(opened)
    if not alternatives:
        return out
    for alt in itertools.islice(_split_triangles(pts, 0, True), 8):
        add(alt)
        if len(out) >= 4:
            break
    # strict fits: a small triangle hanging at a corner of a large one is not absorbed
    if budget is None:
        budget = [_STRICT_BUDGET]  # triangle fits: bounds the work on non-tags (text, markers)
    for tol_px, notch in itertools.product((1.5, 2.5), (False, True)):
        for strict in itertools.islice(_split_triangles(pts, 0, notch, tol_px, budget), 2):
            add(strict)
    return out


def _split_triangles(
    pts: NDArray[Any],
    depth: int,
    notch: bool,
    strict: float = 0.0,
    budget: list[int] | None = None,
    fitted: bool = False,
) -> Iterator[list[NDArray[np.float64]]]:
    """Triangles of a contour that may be several triangles joined at shared vertices.

    A union of triangles meeting at a vertex has concave corners there (convexity defects) on
    both sides of the shared vertex (or a defect and the bottom of the notch the blur filled):
    the contour is cut between two such concave points, shortest cut first (or from a concave
    point to a contour point within 3 px, a pinch; with ``notch`` also along a slit, see
    :func:`_notch_cuts`), and both halves are fitted again, recursively. Yields the
    decompositions found, in the order of the cuts. ``fitted``: the caller already knows
    that ``pts`` is not one (loosely fitted) triangle.
    """
    if budget is not None:
        if budget[0] <= 0:
            return
        budget[0] -= 1
    tri = None if fitted and not strict else _triangle_fit(pts, strict)
    if tri is not None:
        yield tri
        return
    n = len(pts)
    if depth >= 4 or n < 16:
        return
    c = pts.reshape(-1, 1, 2).astype(np.int32)
    try:
        hull = np.sort(cv2.convexHull(c, returnPoints=False).ravel()).reshape(-1, 1)
        defects = cv2.convexityDefects(c, hull.astype(np.int32))
    except cv2.error:
        return
    if defects is None:
        return
    dfs = defects.reshape(-1, 4)
    if strict:
        # every reflex corner of the polygon approximation (a union of triangles meeting at
        # vertices has its reflex corners exactly at the shared vertices; a hull gap holding
        # several of them gives only one convexity defect)
        extra = _reflex_corners(pts)
        if len(extra):
            dfs = np.concatenate([dfs, extra[~np.isin(extra[:, 2], dfs[:, 2])]])
    dfs = dfs[dfs[:, 3] >= 180]  # deeper than 0.7 px
    if len(dfs) == 0:
        return
    flat = pts.reshape(-1, 2).astype(np.float64)
    min_sep = 8 if strict else max(8, n // 12)  # strict: tiny triangles at a pinch too
    far_pts = np.unique(dfs[:, 2])
    # cuts between two concave points (both sides of a shared vertex), shortest first; then
    # from a concave point to a contour point at most 3 px away (a pinch the hull hides)
    cuts: list[tuple[float, int, int]] = []
    cut_max = max(4.0, 0.2 * math.sqrt(abs(float(cv2.contourArea(c)))))
    if len(far_pts) > 1:
        uu, vv = _upper_pairs(len(far_pts))
        fi, fj = far_pts[uu], far_pts[vv]
        gap = np.abs(fi - fj)
        pair_d = flat[fi] - flat[fj]
        pair_len = np.hypot(pair_d[:, 0], pair_d[:, 1])
        ok = (np.minimum(gap, n - gap) >= min_sep) & (pair_len <= cut_max)
        cuts = list(zip(pair_len[ok].tolist(), fi[ok].tolist(), fj[ok].tolist(), strict=True))
    cuts.sort()
    cuts = cuts[:5]
    idx = np.arange(n)
    for far in dfs[np.argsort(-dfs[:, 3])][: 12 if strict else 3, 2]:
        i = int(far)
        arc = np.abs(idx - i)
        arc = np.minimum(arc, n - arc)
        dist = np.hypot(flat[:, 0] - flat[i, 0], flat[:, 1] - flat[i, 1])
        dist[arc < min_sep] = np.inf
        j = int(np.argmin(dist))
        if dist[j] <= 3.0:
            cuts.append((float(dist[j]), i, j))
    if notch:
        cuts += _notch_cuts(flat, dfs, min_sep)
    tried: set[tuple[int, int]] = set()
    for _, i, j in cuts:
        a, b = sorted((i, j))
        if (a, b) in tried:
            continue
        tried.add((a, b))
        rights: list[list[NDArray[np.float64]]] | None = None
        for left in _split_triangles(pts[a : b + 1], depth + 1, notch, strict, budget):
            if rights is None:
                rest = np.concatenate([pts[b:], pts[: a + 1]])
                rights = list(itertools.islice(_split_triangles(rest, depth + 1, notch, strict, budget), 2))
            if not rights:
                break
            for right in rights:
                yield left + right


@functools.lru_cache(maxsize=64)
def _upper_pairs(m: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """``np.triu_indices(m, 1)`` (cached: read-only)."""
    u, v = np.triu_indices(m, 1)
    u.flags.writeable = False
    v.flags.writeable = False
    return u, v


def _reflex_corners(pts: NDArray[Any]) -> NDArray[np.int64]:
    """Reflex corners of a contour's polygon approximation as convexity-defect rows
    ``(start, end, corner, depth × 256)``: start/end the neighbouring polygon corners, depth the
    corner's distance from their chord (contour indices)."""
    n = len(pts)
    flat = pts.reshape(-1, 2)
    c = flat.reshape(-1, 1, 2).astype(np.int32)
    poly = cv2.approxPolyDP(c, 1.0, True).reshape(-1, 2)
    m = len(poly)
    if m < 4:
        return np.zeros((0, 4), dtype=np.int64)
    # contour index of every polygon corner (approxPolyDP keeps contour order)
    idx = np.empty(m, dtype=np.int64)
    k = 0
    for r in range(m):
        hits = np.nonzero((flat[k:, 0] == poly[r, 0]) & (flat[k:, 1] == poly[r, 1]))[0]
        if len(hits) == 0:
            hits = np.nonzero((flat[:, 0] == poly[r, 0]) & (flat[:, 1] == poly[r, 1]))[0]
            if len(hits) == 0:
                return np.zeros((0, 4), dtype=np.int64)
            k = int(hits[0])
        else:
            k += int(hits[0])
        idx[r] = k
    pf = poly.astype(np.float64)
    prv = np.roll(pf, 1, axis=0)
    nxt = np.roll(pf, -1, axis=0)
    cross = (pf[:, 0] - prv[:, 0]) * (nxt[:, 1] - pf[:, 1]) - (pf[:, 1] - prv[:, 1]) * (nxt[:, 0] - pf[:, 0])
    orient = np.sign(float(cv2.contourArea(c, oriented=True)))
    # OpenCV's oriented area is positive for a clockwise contour on screen (y down), whose
    # convex corners then turn with a positive cross product
    reflex = cross * orient < 0
    chord = nxt - prv
    depth = np.abs(chord[:, 0] * (pf[:, 1] - prv[:, 1]) - chord[:, 1] * (pf[:, 0] - prv[:, 0]))
    depth /= np.maximum(np.hypot(chord[:, 0], chord[:, 1]), 1e-9)
    rows: NDArray[np.int64] = np.stack([np.roll(idx, 1), np.roll(idx, -1), idx, (depth * 256).astype(np.int64)], axis=1)
    out: NDArray[np.int64] = rows[reflex & (idx < n)]
    return out


def _notch_cuts(flat: _F64, dfs: NDArray[Any], min_sep: int) -> list[tuple[float, int, int]]:
    """Cuts that continue a slit from its bottom (a concave point) to where it leaves the shape.

    Two triangles that share a vertex at a narrow angle leave a slit between them that the
    blur closes near the vertex: the union's contour has one concave point (the slit bottom)
    and the shared vertex is a convex corner on the far side. The cut runs from the concave
    point straight on, along the slit (from the middle of the notch's mouth through its
    bottom, or along the bisector of its walls), to where the ray leaves the component, and
    ends at the contour point there that lies farthest along the ray (the shared tip).
    """
    n = len(flat)
    lo = flat.min(axis=0) - 1
    size = (flat.max(axis=0) - lo + 2).astype(np.int64)
    mask = np.zeros((int(size[1]), int(size[0])), dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(flat - lo).astype(np.int32).reshape(-1, 1, 2)], 1)
    reach = float(np.hypot(*size))
    steps = np.arange(1.0, reach, 0.5)
    out: list[tuple[float, int, int]] = []
    idx = np.arange(n)
    walls = max(3, min(10, n // 24))
    for s_, e_, far, _depth in dfs[np.argsort(-dfs[:, 3])][:4]:
        i = int(far)
        p = flat[i]
        u1 = flat[(i - walls) % n] - p
        u2 = flat[(i + walls) % n] - p
        bis = -(u1 / max(float(np.hypot(*u1)), 1e-9) + u2 / max(float(np.hypot(*u2)), 1e-9))
        mouth = p - 0.5 * (flat[int(s_)] + flat[int(e_)])
        arc = np.abs(idx - i)
        arc = np.minimum(arc, n - arc)
        for d in (mouth, bis):
            ln = float(np.hypot(*d))
            if ln < 1e-6:
                continue
            d = d / ln
            ray = p + steps[:, None] * d
            rc = np.round(ray - lo).astype(np.int64)
            ok = (rc[:, 0] >= 0) & (rc[:, 1] >= 0) & (rc[:, 0] < size[0]) & (rc[:, 1] < size[1])
            inside = np.zeros(len(steps), dtype=bool)
            inside[ok] = mask[rc[ok, 1], rc[ok, 0]] > 0
            outside = np.nonzero(~inside)[0]
            last = (int(outside[0]) if len(outside) else len(steps)) - 1
            if last < 2:
                continue
            exit_pt = ray[last]
            dist = np.linalg.norm(flat - exit_pt, axis=1)
            near = (dist <= max(3.0, 0.08 * steps[last])) & (arc >= min_sep)
            if not near.any():
                continue
            along = np.where(near, (flat - p) @ d, -np.inf)
            j = int(np.argmax(along))
            out.append((100.0 + float(steps[last]), i, j))
    return out


def _triangles_by_opening(
    fg: NDArray[Any], contours: Any, hier: NDArray[Any], index: int
) -> list[NDArray[np.float64]] | None:
    """Paper's fallback: open one component with a 3×3 kernel and fit its parts."""
    x, y, w, h = cv2.boundingRect(contours[index])
    x0, y0 = max(x - 2, 0), max(y - 2, 0)
    x1, y1 = min(x + w + 2, fg.shape[1]), min(y + h + 2, fg.shape[0])
    comp = np.zeros((y1 - y0, x1 - x0), dtype=np.uint8)
    cv2.drawContours(comp, contours, index, 255, cv2.FILLED, cv2.LINE_8, hier, 1, (-x0, -y0))
    comp &= fg[y0:y1, x0:x1]
    opened = cv2.morphologyEx(comp, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    parts, ph = cv2.findContours(opened, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if ph is None:
        return None
    out: list[NDArray[np.float64]] = []
    offset = np.array([x0, y0], dtype=np.float64)
    for k, c in enumerate(parts):
        if ph[0][k][3] >= 0:
            if len(c) >= 8:
                return None
            continue
        if len(c) < 8:
            continue
        tri = _triangle_fit(c.reshape(-1, 2))
        if tri is None:
            return None
        out.extend(ch + offset for ch in tri)
    return out or None


def _bad_triangles(verts: _F64, quad: _F64, side: float) -> str:
    """Why fitted triangles cannot be a tag's (``""`` if they can).

    The vertices must be finite and inside the data area, and no two triangles may share
    part of a side: tag triangles meet only at shared vertices, while a cut through one
    triangle (a wrong split) leaves two triangles on both sides of one line segment.
    """
    if not np.isfinite(verts).all():
        return "degenerate triangle"
    v = verts.reshape(-1, 2)
    # inside the data area: on the inner side of every quad side (convex, either orientation)
    a = quad
    d = quad[_NEXT4] - a
    cross = d[None, :, 0] * (v[:, None, 1] - a[None, :, 1]) - d[None, :, 1] * (v[:, None, 0] - a[None, :, 0])
    cross /= np.hypot(d[:, 0], d[:, 1])[None, :]
    slack = 1.0 + 0.01 * side
    if not ((cross >= -slack).all(axis=1).all() or (cross <= slack).all(axis=1).all()):
        return "triangle vertex outside the data area"
    t = len(verts)
    if t < 2:
        return ""
    near = max(0.8, 0.008 * side)
    sa = verts.reshape(-1, 2)  # side j of triangle i runs from vertex j to j + 1
    sb = verts[:, _NEXT3].reshape(-1, 2)
    sd = sb - sa
    ln = np.maximum(np.hypot(sd[:, 0], sd[:, 1]), 1e-9)
    unit = sd / ln[:, None]
    nrm = np.stack([-unit[:, 1], unit[:, 0]], axis=1)
    # side j against side i: both ends of j within ``near`` of side i's line, and their
    # projections overlapping side i over a third of the shorter side
    off_a = np.abs(((sa[None, :, :] - sa[:, None, :]) * nrm[:, None, :]).sum(axis=2))
    off_b = np.abs(((sb[None, :, :] - sa[:, None, :]) * nrm[:, None, :]).sum(axis=2))
    pa = ((sa[None, :, :] - sa[:, None, :]) * unit[:, None, :]).sum(axis=2)
    pb = ((sb[None, :, :] - sa[:, None, :]) * unit[:, None, :]).sum(axis=2)
    overlap = np.minimum(np.maximum(pa, pb), ln[:, None]) - np.maximum(np.minimum(pa, pb), 0.0)
    own = _same_triangle(len(sa))
    shared = (off_a < near) & (off_b < near) & (overlap > np.minimum(ln[:, None], ln[None, :]) / 3) & ~own
    if shared.any():
        return "two triangles share part of a side"
    return ""


def _fit_chains(chains: list[NDArray[np.float64]]) -> tuple[_F64, _F64]:
    """Least-squares lines (unit normal n, offset c with n·x = c) of point chains."""
    lens = np.array([len(c) for c in chains])
    allp = np.concatenate(chains)
    starts = np.concatenate([[0], np.cumsum(lens)[:-1]])
    sx = np.add.reduceat(allp[:, 0], starts)
    sy = np.add.reduceat(allp[:, 1], starts)
    mx, my = sx / lens, sy / lens
    rep = np.repeat(np.arange(len(chains)), lens)
    dx = allp[:, 0] - mx[rep]
    dy = allp[:, 1] - my[rep]
    return _lines_from_moments(
        mx, my, np.add.reduceat(dx * dx, starts), np.add.reduceat(dx * dy, starts),
        np.add.reduceat(dy * dy, starts),
    )  # fmt: skip


def _lines_from_moments(mx: _F64, my: _F64, sxx: _F64, sxy: _F64, syy: _F64) -> tuple[_F64, _F64]:
    theta = 0.5 * np.arctan2(2 * sxy, sxx - syy)  # direction of largest spread
    normal = np.stack([-np.sin(theta), np.cos(theta)], axis=1)
    offset = normal[:, 0] * mx + normal[:, 1] * my
    return normal, offset


def _lines_through(poly: _F64) -> tuple[_F64, _F64]:
    """Lines of the sides of one closed polygon (side i from vertex i to i+1)."""
    a = poly
    b = poly[_next_index(len(poly), len(poly))]
    d = b - a
    normal = np.stack([-d[:, 1], d[:, 0]], axis=1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return normal, (normal * a).sum(axis=1)


def _intersect(n1: _F64, c1: _F64, n2: _F64, c2: _F64) -> _F64:
    det = n1[:, 0] * n2[:, 1] - n1[:, 1] * n2[:, 0]
    det[det == 0] = np.nan  # parallel lines: no intersection (NaN, without a warning)
    out: _F64 = np.empty((len(det), 2))
    out[:, 0] = (c1 * n2[:, 1] - c2 * n1[:, 1]) / det
    out[:, 1] = (n1[:, 0] * c2 - n2[:, 0] * c1) / det
    return out


def _polygon_vertices(normal: _F64, offset: _F64, m: int) -> _F64:
    """Vertices of polygons of ``m`` sides each: vertex j = side j−1 ∩ side j."""
    prev = _prev_index(len(offset), m)
    v = _intersect(normal[prev], offset[prev], normal, offset)
    return v.reshape(-1, m, 2) if m != 4 else v.reshape(-1, 2)


@functools.lru_cache(maxsize=256)
def _prev_index(s: int, m: int) -> NDArray[np.intp]:
    """Index of side j−1 of the same polygon for every side of ``s / m`` polygons of ``m`` sides
    (cached: read-only)."""
    i = np.arange(s)
    out: NDArray[np.intp] = i - i % m + (i - 1) % m
    out.flags.writeable = False
    return out


@functools.lru_cache(maxsize=256)
def _next_index(s: int, m: int) -> NDArray[np.intp]:
    """Index of side j+1 of the same polygon (see :func:`_prev_index`)."""
    i = np.arange(s)
    out: NDArray[np.intp] = i - i % m + (i + 1) % m
    out.flags.writeable = False
    return out


def _triangle_vertices(normal: _F64, offset: _F64) -> _F64:
    """``(T, 3, 2)`` vertices of triangles given by 3 consecutive side lines each.

    Side j of a triangle runs from vertex j to vertex j+1, so vertex j = side j−1 ∩ side j.
    """
    return _polygon_vertices(normal, offset, 3).reshape(-1, 3, 2)


def _refine_lines(
    img: NDArray[np.float32],
    normal: _F64,
    offset: _F64,
    tri_verts: _F64,
    level: float,
    quad: _F64 | None = None,
) -> tuple[_F64, _F64]:
    """Move each side line to the ``level`` crossings of the grey image along its normals.

    The lines are the sides of the triangles ``tri_verts`` ``(T, 3, 2)`` (side j runs from
    vertex j to j+1; vertex j lies on lines j−1 and j), followed, when ``quad`` ``(4, 2)`` is
    given, by the 4 sides of the data area through its corners: one pass (one ``remap``)
    refines both. Samples 16 positions on the middle 84 % of each side, 13 offsets in ±3 px
    (bilinear), takes the crossing nearest the line and refits by least squares. Sides with
    fewer than 3 crossings keep their line.

    A triangle sample counts only where the shape is wide enough: its distance to every other
    triangle side must be at least ``min(3 px, 0.6 × the side's widest sample)``. Across a
    sliver narrower than the blur the grey level never reaches the bright level and the
    crossings move inward, which would make needle tips overshoot along their axis.
    """
    at = tri_verts.reshape(-1, 2)
    st = len(at)
    if quad is not None:
        a = np.concatenate([at, quad])
        b = np.concatenate([at[_next_index(st, 3)], quad[_NEXT4]])
    else:
        a = at
        b = at[_next_index(st, 3)]
    s = len(a)
    finite: NDArray[np.bool_] | bool = True
    if not np.isfinite(at).all():  # parallel lines: those sides keep their line
        finite = np.asarray(np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1), dtype=bool)
        a = np.where(finite[:, None], a, 0.0)
        b = np.where(finite[:, None], b, 0.0)
    sd = b - a
    # sample positions along each side (the vertices lie on their lines: no projection needed)
    base = a[:, None, :] + _REFINE_FR[None, :, None] * sd[:, None, :]  # (S, M, 2)
    # distance of every triangle sample to every other triangle side segment
    sdt = sd[:st]
    ln2 = np.maximum((sdt * sdt).sum(axis=1), 1e-12)
    rel = base[:st, :, None, :] - a[None, None, :st, :]  # (St, M, St, 2)
    u = np.clip(np.einsum("ijkl,kl->ijk", rel, sdt) / ln2, 0.0, 1.0)
    rel -= u[..., None] * sdt
    gap = np.einsum("ijkl,ijkl->ijk", rel, rel)
    gap[np.arange(st), :, np.arange(st)] = np.inf
    width = np.sqrt(gap.min(axis=2))  # (St, M)
    wide = np.ones((s, len(_REFINE_FR)), dtype=bool)
    wide[:st] = width >= np.minimum(3.0, 0.6 * width.max(axis=1))[:, None]
    offs = _REFINE_OFFS
    n_o = len(offs)
    samp = base[:, :, None, :] + offs[None, None, :, None] * normal[:, None, None, :]  # (S, M, O, 2)
    samp32 = samp.astype(np.float32).reshape(-1, n_o, 2)
    vals32 = cv2.remap(img, samp32, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)  # type: ignore[call-overload]
    vals = vals32.reshape(s * len(_REFINE_FR), n_o).astype(np.float64) - level
    above = vals > 0
    change = above[:, 1:] != above[:, :-1]  # crossing between o and o+1
    j = np.argmin(np.where(change, _REFINE_MID, np.inf), axis=1)
    rows = np.arange(len(vals))
    v0 = vals[rows, j]
    den = v0 - vals[rows, j + 1]
    step = den != 0
    o = offs[j] + np.where(step, v0 / np.where(step, den, 1.0), 0.5) * (offs[1] - offs[0])
    valid = (change.any(axis=1) & wide.ravel()).reshape(s, -1)
    pts = base + o.reshape(s, -1)[:, :, None] * normal[:, None, :]
    w = valid.astype(np.float64)
    cnt = w.sum(axis=1)
    good = (cnt >= 3) & finite
    cnt_safe = np.maximum(cnt, 1)
    px, py = pts[..., 0], pts[..., 1]
    mx_ = (w * px).sum(axis=1) / cnt_safe
    my_ = (w * py).sum(axis=1) / cnt_safe
    dx = px - mx_[:, None]
    dy = py - my_[:, None]
    wdx = w * dx
    n2, c2 = _lines_from_moments(mx_, my_, (wdx * dx).sum(axis=1), (wdx * dy).sum(axis=1), (w * dy * dy).sum(axis=1))
    # keep the orientation of the old normal
    flip = (n2 * normal).sum(axis=1) < 0
    n2[flip] *= -1
    c2[flip] *= -1
    return np.where(good[:, None], n2, normal), np.where(good, c2, offset)


_REFINE_FR = np.linspace(0.08, 0.92, 16)
_REFINE_OFFS = np.linspace(-3.0, 3.0, 13)
_REFINE_MID = np.abs(0.5 * (_REFINE_OFFS[1:] + _REFINE_OFFS[:-1]))


@functools.lru_cache(maxsize=32)
def _same_triangle(s: int) -> NDArray[np.bool_]:
    """``(s, s)`` mask of side pairs of one triangle (sides 3t, 3t+1, 3t+2; cached: read-only)."""
    t = np.arange(s) // 3
    out: NDArray[np.bool_] = t[:, None] == t[None, :]
    out.flags.writeable = False
    return out


def _ls_point_lists(nl: list[list[float]], ol: list[float], ids: list[int]) -> tuple[tuple[float, float] | None, float]:
    """Least-squares intersection of the lines ``ids`` (normals ``nl``, offsets ``ol``: n·x = c)
    and the largest line distance to it; plain Python (the few lines of one point, no array
    overhead). None, inf for (nearly) parallel lines."""
    a00 = a01 = a11 = b0 = b1 = 0.0
    for i in ids:
        nx, ny = nl[i]
        c = ol[i]
        a00 += nx * nx
        a01 += nx * ny
        a11 += ny * ny
        b0 += nx * c
        b1 += ny * c
    det = a00 * a11 - a01 * a01
    if abs(det) < 1e-9:
        return None, math.inf
    x = (b0 * a11 - a01 * b1) / det
    y = (a00 * b1 - a01 * b0) / det
    return (x, y), max(abs(nl[i][0] * x + nl[i][1] * y - ol[i]) for i in ids)


def _cluster_hypotheses(
    verts: _F64, normal: _F64, offset: _F64, cap: float, sure: float, tol: float, max_doubtful: int = 4
) -> list[tuple[_F64, list[NDArray[np.int64]]]]:
    """Point hypotheses from the triangle vertex estimates, most merges first.

    Estimates of different triangles may be one shared point when the least-squares
    intersection of all their side lines stays within ``tol`` px of every line (estimates at
    most ``cap`` px apart). Merges of estimates closer than ``sure`` px are always made; up to
    ``max_doubtful`` farther ones (sharp tips give long error ellipses along the bisector) are
    tried in and out, and the decoder keeps the first hypothesis that reads and verifies.
    Each point is the least-squares intersection of its side lines; each hypothesis comes
    with the indices of the side lines through each of its points.
    """
    v = verts.reshape(-1, 2)
    n = len(v)
    tri, lid, other = _vertex_tables(n)
    nl: list[list[float]] = normal.tolist()
    ol: list[float] = offset.tolist()
    dv = v[:, None, :] - v[None, :, :]
    d = np.sqrt((dv * dv).sum(axis=2))
    ii, jj = np.nonzero((d < cap) & other)
    order = np.argsort(d[ii, jj], kind="stable")
    sure_pairs: list[tuple[int, int]] = []
    doubtful: list[tuple[int, int]] = []
    for o in order:
        i, j = int(ii[o]), int(jj[o])
        _, res = _ls_point_lists(nl, ol, lid[i] + lid[j])
        if res > tol:
            continue
        (sure_pairs if d[i, j] <= sure else doubtful).append((i, j))
    doubtful = doubtful[:max_doubtful]
    subsets = sorted(itertools.product((True, False), repeat=len(doubtful)), key=lambda s: -sum(s))
    out: list[tuple[_F64, list[NDArray[np.int64]]]] = []
    seen: set[tuple[int, ...]] = set()
    for subset in subsets:
        pairs = sure_pairs + [pr for pr, use in zip(doubtful, subset, strict=True) if use]
        groups = _merge(pairs, n, tri, lid, nl, ol, tol)
        key = tuple(sorted(min(g) for g in groups))
        if key in seen:
            continue
        seen.add(key)
        pts = []
        lines = []
        for members in groups:
            id_list = [u for m in members for u in lid[m]]
            xy, _ = _ls_point_lists(nl, ol, id_list)
            if xy is None or not (math.isfinite(xy[0]) and math.isfinite(xy[1])):
                break
            pts.append(xy)
            lines.append(np.array(id_list, dtype=np.int64))
        else:
            out.append((np.array(pts, dtype=np.float64), lines))
    return out


@functools.lru_cache(maxsize=32)
def _vertex_tables(n: int) -> tuple[NDArray[np.int64], list[list[int]], NDArray[np.bool_]]:
    """For ``n`` triangle vertex estimates (vertex j of triangle t at 3t + j): the triangle of
    each, the two side lines through each (side j runs from vertex j to j+1) and the mask
    of pairs ``i < j`` of different triangles (cached: read-only)."""
    tri = np.arange(n) // 3
    corner = np.arange(n) % 3
    lid = np.stack([3 * tri + (corner + 2) % 3, 3 * tri + corner], axis=1).tolist()
    other = np.triu(tri[:, None] != tri[None, :], 1)
    for arr in (tri, other):
        arr.flags.writeable = False
    return tri, lid, other


def _merge(
    pairs: list[tuple[int, int]],
    n: int,
    tri: NDArray[np.int64],
    lid: list[list[int]],
    nl: list[list[float]],
    ol: list[float],
    tol: float,
) -> list[list[int]]:
    """Greedy union of vertex estimates along ``pairs`` (never two corners of one triangle)."""
    groups: dict[int, list[int]] = {i: [i] for i in range(n)}
    root = list(range(n))
    for i, j in pairs:
        a, b = root[i], root[j]
        if a == b:
            continue
        ga, gb = groups[a], groups[b]
        if {m // 3 for m in ga} & {m // 3 for m in gb}:  # vertex m is a corner of triangle m // 3
            continue
        if len(ga) + len(gb) > 2:
            _, res = _ls_point_lists(nl, ol, [u for m in ga + gb for u in lid[m]])
            if res > tol:
                continue
        groups[a] = ga + gb
        for m in gb:
            root[m] = a
        del groups[b]
    return list(groups.values())


def _margin(pts: _F64) -> float:
    """Smallest distance (px) from a point to the line through two other points."""
    return _cross_table(pts)[1]


@functools.lru_cache(maxsize=16)
def _pair_tables(k: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
    """Pairs ``i < j`` of ``k`` points and the mask of (pair, point) entries where the point is
    one of the pair (cached: read-only)."""
    i, j = _upper_pairs(k)
    idx = np.arange(k)
    own = (idx[None, :] == i[:, None]) | (idx[None, :] == j[:, None])
    own.flags.writeable = False
    return i, j, own


def _cross_table(pts: _F64) -> tuple[_F64, float]:
    """Orientation values of every pair ``i < j`` against every point (``(P, k)``, the brief's
    convention: negative = left of i→j) and the margin (smallest point-to-line distance, px)."""
    i, j, own = _pair_tables(len(pts))
    a = pts[i]
    d = pts[j] - a
    cross = d[:, None, 0] * (pts[None, :, 1] - a[:, None, 1]) - d[:, None, 1] * (pts[None, :, 0] - a[:, None, 0])
    ln = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
    dist = np.abs(cross) / ln[:, None]
    dist[own] = np.inf
    return cross, float(dist.min())


def _read_orderings(pts: _F64) -> tuple[float, list[tuple[tuple[int, ...], NDArray[np.int8]]]]:
    """Margin (px) and the canonical orderings of one detected point set, smallest λ first.

    λ comes from the orientation table the margin is computed from (one table for both).
    """
    k = len(pts)
    cross, margin = _cross_table(pts)
    if not margin > 0:
        return margin, []
    i, j, own = _pair_tables(k)
    left = np.count_nonzero((cross < 0) & ~own, axis=1)
    lam = np.zeros((k, k), dtype=np.int64)
    lam[i, j] = left
    lam[j, i] = k - 2 - left
    return margin, lambda_orderings(lam)


@dataclass(frozen=True)
class _LineSystem:
    """The side lines of one point hypothesis, stacked and normalised once for every
    (realization, labeling) fit: unit normals ``nrm``, offsets ``off`` (n·x = c), the input
    index of each line's point ``owner``, the lines in normalised homogeneous form ``lh`` and
    the de-normalising map ``ti_inv``."""

    nrm: _F64
    off: _F64
    owner: NDArray[np.intp]
    lh: _F64
    ti_inv: _F64


def _line_system(lines: list[tuple[_F64, _F64]]) -> _LineSystem | None:
    """Stack and normalise the side lines of a hypothesis (None if fewer than 8: no fit)."""
    nrm, off, owner = _stack_lines(lines)
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
    return _LineSystem(nrm, off, owner, lh, ti_inv)


@dataclass(frozen=True)
class _Model:
    """A stored realization for the homography fit: its points ``(k, 2)`` (tag-plane units),
    the points normalised to zero mean and mean distance √2 in homogeneous form ``xs``
    ``(k, 3)``, and the normalising map ``tm`` (3 × 3)."""

    points: _F64
    xs: _F64
    tm: _F64


def _model(src: _F64) -> _Model:
    """Normalise one realization for :func:`_homography_lines` (computed once per ID)."""
    mc = src.mean(axis=0)
    dm = src - mc
    ms = math.sqrt(2.0) / max(float(np.sqrt((dm * dm).sum(axis=1)).mean()), 1e-12)
    xs = np.empty((len(src), 3))
    xs[:, :2] = dm * ms
    xs[:, 2] = 1.0
    tm = np.array([[ms, 0, -ms * mc[0]], [0, ms, -ms * mc[1]], [0, 0, 1.0]])
    return _Model(src, xs, tm)


def _homography_lines(model: _Model, system: _LineSystem, rep: NDArray[np.intp]) -> _F64 | None:
    """Homography mapping each model point onto the side lines through its detected point.

    ``rep[l]`` is the index in ``model.points`` of the model point of line ``l``. Linear least
    squares (normalised DLT) on the incidences ``l·H·x = 0`` of every model point ``x`` with
    every image line ``l`` fitted through the detected point; a vertex is thus constrained
    across each of its sides, where it is measured well, and not along the axis of a sharp tip,
    where the side lines meet at a small angle. Falls back to None when the system is
    degenerate.
    """
    lh = system.lh
    a = (lh[:, :, None] * model.xs[rep][:, None, :]).reshape(len(lh), 9)
    try:
        # the least-squares null vector: eigenvector of the smallest eigenvalue of AᵀA (9 × 9;
        # cheaper than the SVD of A, and the normalisation keeps AᵀA well conditioned)
        _, vecs = np.linalg.eigh(a.T @ a)
    except np.linalg.LinAlgError:
        return None
    hmat = system.ti_inv @ vecs[:, 0].reshape(3, 3) @ model.tm
    if not np.isfinite(hmat).all() or abs(hmat[2, 2]) < 1e-12:
        return None
    out: _F64 = hmat / hmat[2, 2]
    return out


def _map_corners_back(hmat: _F64, corners: _F64) -> list[list[float]] | None:
    """The 4 image ``corners`` mapped to the tag plane by ``hmat``⁻¹ (plain Python: a 3 × 3
    adjugate and 4 points), or None when ``hmat`` is singular or a corner maps to infinity."""
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


def _stack_lines(lines: list[tuple[_F64, _F64]]) -> tuple[_F64, _F64, NDArray[np.intp]]:
    """All side lines of a point list in one array, and the index of each line's point."""
    nrm = np.concatenate([n for n, _ in lines])
    off = np.concatenate([c for _, c in lines])
    rep = np.repeat(np.arange(len(lines)), [len(c) for _, c in lines])
    return nrm, off, rep


def _apply_h(hmat: _F64, pts: _F64) -> _F64:
    ph = pts @ hmat[:, :2].T + hmat[:, 2]
    w = ph[:, 2:3]
    if w.all():
        out: _F64 = ph[:, :2] / w
        return out
    with np.errstate(divide="ignore", invalid="ignore"):
        out = ph[:, :2] / w
    return out
