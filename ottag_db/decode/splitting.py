"""Splitting stage: cut a component that is several triangles joined at vertices into triangles."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.single_set import pair_table
from ottag_db.decode.triangles import TriangleFit, off_triangle, strict_chains, triangle_fit_parts

__all__ = [
    "FRAME_SEARCH",
    "RECTIFIED_SEARCH",
    "FitBudget",
    "FitMemo",
    "SearchBudget",
    "component_decompositions",
    "notch_cuts",
    "reflex_corners",
    "split_triangles",
]

_F64 = NDArray[np.float64]
_Chains = list[_F64]


@dataclass(frozen=True)
class SearchBudget:
    """What the alternative decompositions of one data area may cost, in triangle fits of all
    its components together: the search for slit (notch) cuts, and the strict fits. Bounds the
    work on non-tags (text, markers), whose notched contours offer thousands of cuts."""

    notch_fits: int
    strict_fits: int


#: The reading of a candidate in the frame. Each component of an ArUco marker or a word offers
#: slit cuts: with 400 notch fits per component and 160 strict fits, the decoder took 250–270
#: ms per frame on the 100 ArUco frames of benchmarks/decode_speed.py (57–62 ms with this
#: budget; ArUco itself 3 ms). On 1,000 tag frames (grazing views,
#: 4–8 m) the same tags read with 16 / 8 fits as with the old budget; one tag of the distance
#: sweep (benchmarks/decode_sweeps.py, 3.5 m) needs 60 / 20. The rectified view keeps more.
FRAME_SEARCH = SearchBudget(notch_fits=60, strict_fits=20)
#: The rectified view of a foreshortened candidate (:mod:`~ottag_db.decode.rectify`). With
#: 1,200 notch / 160 strict fits (400 for each of three components, as before the budget was
#: shared) an ArUco marker seen at 76–88° cost 350–450 ms per frame, 260–315 of them here;
#: with 300 / 60 fits 220–310 ms (two runs of 80 frames). The tags read the same on 480 grazing
#: frames (78–86°) and on the tilt sweep's 600 frames at 60–89° (benchmarks/decode_sweeps.py)
#: with 300 / 60 fits and with these 100 / 30 (and so they did on 2,000 grazing frames of
#: tests/support/grazing.py, on the usual and a dark frame): on the 40 oblique markers of
#: benchmarks/decode_clutter.py 240 → 152 triangle fits and 174 → 163 ms per frame (most of
#: the rest is the reading by model).
RECTIFIED_SEARCH = SearchBudget(notch_fits=100, strict_fits=30)


@dataclass
class FitBudget:
    """How many more triangle fits a search may make (a counter owned by one reading)."""

    remaining: int

    def take(self) -> bool:
        """Spend one fit; False (and nothing spent) when the budget is used up."""
        if self.remaining <= 0:
            return False
        self.remaining -= 1
        return True


#: A cut of a contour: ``(rank, i, j)``, a sort key and the contour indices of its two ends.
_Cut = tuple[float, int, int]


@dataclass
class FitMemo:
    """Triangle fits and cuts already computed for the contours of one data-area reading.

    The searches for alternative decompositions fit the same sub-contours again (two cuts in
    either order give the same pieces; the strict searches repeat the notch search's cuts): on
    the ArUco frames of benchmarks/decode_speed.py half of the fits were repeats. A memo only
    saves the work: every search still spends its :class:`FitBudget` per fit, so the
    decompositions found are the same. Owned by one reading and dropped with it.
    """

    fits: dict[tuple[str, tuple[int, ...], bytes], TriangleFit | None] = field(default_factory=dict)
    cuts: dict[tuple[str, tuple[int, ...], bytes, bool, bool], list[_Cut]] = field(default_factory=dict)

    def fit(self, pts: NDArray[Any]) -> TriangleFit | None:
        """:func:`~ottag_db.decode.triangles.triangle_fit_parts` of ``pts``, computed once."""
        key = (pts.dtype.str, pts.shape, pts.tobytes())
        if key not in self.fits:
            self.fits[key] = triangle_fit_parts(pts)
        return self.fits[key]

    def cuts_of(self, pts: NDArray[Any], notch: bool, strict: bool) -> list[_Cut]:
        """:func:`contour_cuts` of ``pts``, computed once."""
        key = (pts.dtype.str, pts.shape, pts.tobytes(), notch, strict)
        if key not in self.cuts:
            self.cuts[key] = contour_cuts(pts, notch, strict)
        return self.cuts[key]


def component_decompositions(
    pts: NDArray[Any],
    opening: Callable[[], _Chains | None],
    alternatives: SearchBudget | None = FRAME_SEARCH,
    notch_budget: FitBudget | None = None,
    strict_budget: FitBudget | None = None,
    memo: FitMemo | None = None,
) -> list[_Chains]:
    """Alternative triangle decompositions of one component contour, most plausible first.

    Parameters
    ----------
    pts : numpy.ndarray
        ``(n, 2)`` integer contour of the component (holes bridged in).
    opening : callable
        The paper's fallback, called at most once: the component's triangles after a 3×3
        opening, or None.
    alternatives : SearchBudget or None
        None: only the splitter's first decomposition (or the opening's, if the splitter
        finds none). Else also the opening, slit cuts and strict fits, within this budget.
    notch_budget, strict_budget : FitBudget or None
        Notch and strict fits left, shared with the data area's other components (None: a
        fresh one of ``alternatives``).
    memo : FitMemo or None
        The reading's fits and cuts so far (None: a fresh one).

    Returns
    -------
    list of list of numpy.ndarray
        Each decomposition as its side chains (three per triangle), without duplicates.
    """
    out: list[_Chains] = []
    keys: set[tuple[float, ...]] = set()

    def add(chains: _Chains) -> None:
        if alternatives is None:
            out.append(chains)  # the first decomposition only: nothing to deduplicate
            return
        key = tuple(sorted(round(float(v), 0) for ch in chains for v in (ch[0, 0], ch[0, 1])))
        if key not in keys:
            keys.add(key)
            out.append(chains)

    if memo is None:
        memo = FitMemo()
    whole = memo.fit(pts)
    first = whole.chains if whole is not None else next(split_triangles(pts, 0, False, fitted=True, memo=memo), None)
    if first is not None:
        add(first)
        if alternatives is None or (
            whole is not None and off_triangle(whole.contour, whole.corners, 1.5) <= max(3, 0.02 * len(whole.contour))
        ):
            return out  # one triangle: nothing to reconsider
    opened = opening()
    if opened is not None:
        add(opened)
    if alternatives is None:
        return out
    # slit cuts: bounded like the strict fits (on the decoder's synthetic tag scenes the last
    # decomposition came after at most 330 fits; the notched contour of a non-tag, e.g. an
    # ArUco marker's cells, took thousands)
    if notch_budget is None:
        notch_budget = FitBudget(alternatives.notch_fits)
    for alt in itertools.islice(split_triangles(pts, 0, True, budget=notch_budget, memo=memo), 8):
        add(alt)
        if len(out) >= 4:
            break
    # strict fits: a small triangle hanging at a corner of a large one is not absorbed
    if strict_budget is None:
        strict_budget = FitBudget(alternatives.strict_fits)
    for tol_px, notch in itertools.product((1.5, 2.5), (False, True)):
        for strict in itertools.islice(split_triangles(pts, 0, notch, tol_px, strict_budget, memo=memo), 2):
            add(strict)
    return out


def split_triangles(
    pts: NDArray[Any],
    depth: int,
    notch: bool,
    strict: float = 0.0,
    budget: FitBudget | None = None,
    fitted: bool = False,
    memo: FitMemo | None = None,
) -> Iterator[_Chains]:
    """Triangles of a contour that may be several triangles joined at shared vertices.

    A union of triangles meeting at a vertex has concave corners there (convexity defects) on
    both sides of the shared vertex (or a defect and the bottom of the notch the blur filled):
    the contour is cut between two such concave points, shortest cut first (or from a concave
    point to a contour point within 3 px, a pinch; with ``notch`` also along a slit, see
    :func:`notch_cuts`), and both halves are fitted again, recursively.

    Parameters
    ----------
    pts : numpy.ndarray
        ``(n, 2)`` integer contour.
    depth : int
        Recursion depth (the search stops at 4).
    notch : bool
        Also try cuts along slits.
    strict : float
        Strict fit tolerance (px) of :func:`~ottag_db.decode.triangles.triangle_fit`, 0 = loose;
        strict searches also cut at every reflex corner of the polygon approximation.
    budget : FitBudget or None
        Fits left for the whole search (None: unbounded).
    fitted : bool
        The caller already knows that ``pts`` is not one (loosely fitted) triangle.
    memo : FitMemo or None
        Fits and cuts of the search so far (None: a fresh one).

    Yields
    ------
    list of numpy.ndarray
        The decompositions found (side chains, three per triangle), in the order of the cuts.
    """
    if budget is not None and not budget.take():
        return
    if memo is None:
        memo = FitMemo()
    tri = None if fitted and not strict else strict_chains(memo.fit(pts), strict)
    if tri is not None:
        yield tri
        return
    n = len(pts)
    if depth >= 4 or n < 16:
        return
    cuts = memo.cuts_of(pts, notch, bool(strict))
    tried: set[tuple[int, int]] = set()
    for _, i, j in cuts:
        a, b = sorted((i, j))
        if (a, b) in tried:
            continue
        tried.add((a, b))
        rights: list[_Chains] | None = None
        for left in split_triangles(pts[a : b + 1], depth + 1, notch, strict, budget, memo=memo):
            if rights is None:
                rest = np.concatenate([pts[b:], pts[: a + 1]])
                rights = list(itertools.islice(split_triangles(rest, depth + 1, notch, strict, budget, memo=memo), 2))
            if not rights:
                break
            for right in rights:
                yield left + right


def contour_cuts(pts: NDArray[Any], notch: bool, strict: bool) -> list[_Cut]:
    """The cuts :func:`split_triangles` tries on a contour, in order.

    Parameters
    ----------
    pts : numpy.ndarray
        ``(n, 2)`` integer contour (n ≥ 16).
    notch : bool
        Also cuts along slits (:func:`notch_cuts`).
    strict : bool
        A strict search: also cuts at every reflex corner (:func:`reflex_corners`), and ends
        may lie closer together.

    Returns
    -------
    list of tuple
        ``(rank, i, j)``: cuts between two concave points (shortest first, at most 5), from a
        concave point to a contour point within 3 px, then (``notch``) along slits.
    """
    n = len(pts)
    c = pts.reshape(-1, 1, 2).astype(np.int32)
    try:
        hull = np.sort(cv2.convexHull(c, returnPoints=False).ravel()).reshape(-1, 1)
        defects = cv2.convexityDefects(c, hull.astype(np.int32))
    except cv2.error:
        return []
    if defects is None:
        return []
    dfs = defects.reshape(-1, 4)
    if strict:
        # every reflex corner of the polygon approximation (a union of triangles meeting at
        # vertices has its reflex corners exactly at the shared vertices; a hull gap holding
        # several of them gives only one convexity defect)
        extra = reflex_corners(pts)
        if len(extra):
            dfs = np.concatenate([dfs, extra[~np.isin(extra[:, 2], dfs[:, 2])]])
    dfs = dfs[dfs[:, 3] >= 180]  # deeper than 0.7 px
    if len(dfs) == 0:
        return []
    flat = pts.reshape(-1, 2).astype(np.float64)
    min_sep = 8 if strict else max(8, n // 12)  # strict: tiny triangles at a pinch too
    far_pts = np.array(sorted(set(dfs[:, 2].tolist())), dtype=dfs.dtype)  # np.unique, without its overhead
    # cuts between two concave points (both sides of a shared vertex), shortest first; then
    # from a concave point to a contour point at most 3 px away (a pinch the hull hides)
    cuts: list[_Cut] = []
    cut_max = max(4.0, 0.2 * math.sqrt(abs(float(cv2.contourArea(c)))))
    if len(far_pts) > 1:
        pairs = pair_table(len(far_pts))
        fi, fj = far_pts[pairs.first], far_pts[pairs.second]
        gap = np.abs(fi - fj)
        pair_d = flat[fi] - flat[fj]
        pair_len = np.hypot(pair_d[:, 0], pair_d[:, 1])
        ok = (np.minimum(gap, n - gap) >= min_sep) & (pair_len <= cut_max)
        cuts = list(zip(pair_len[ok].tolist(), fi[ok].tolist(), fj[ok].tolist(), strict=True))
    cuts.sort()
    cuts = cuts[:5]
    # all concave points at once: (F, n) arcs and distances to every contour point
    fars = dfs[np.argsort(-dfs[:, 3])][: 12 if strict else 3, 2].astype(np.intp)
    arc = np.abs(np.arange(n)[None, :] - fars[:, None])
    arc = np.minimum(arc, n - arc)
    dist = np.hypot(flat[None, :, 0] - flat[fars, 0, None], flat[None, :, 1] - flat[fars, 1, None])
    dist[arc < min_sep] = np.inf
    nearest = dist.argmin(axis=1)
    for i, j, dj in zip(fars.tolist(), nearest.tolist(), dist[np.arange(len(fars)), nearest].tolist(), strict=True):
        if dj <= 3.0:
            cuts.append((dj, i, j))
    if notch:
        cuts += notch_cuts(flat, dfs, min_sep)
    return cuts


def reflex_corners(pts: NDArray[Any]) -> NDArray[np.int64]:
    """Reflex corners of a contour's polygon approximation (1 px) as convexity-defect rows.

    Parameters
    ----------
    pts : numpy.ndarray
        ``(n, 2)`` integer contour.

    Returns
    -------
    numpy.ndarray
        ``(r, 4)`` int64 rows ``(start, end, corner, depth × 256)``: start/end the
        neighbouring polygon corners, depth the corner's distance from their chord (pixels);
        the first three are contour indices.
    """
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


def notch_cuts(flat: _F64, dfs: NDArray[Any], min_sep: int) -> list[_Cut]:
    """Cuts that continue a slit from its bottom (a concave point) to where it leaves the shape.

    Two triangles that share a vertex at a narrow angle leave a slit between them that the
    blur closes near the vertex: the union's contour has one concave point (the slit bottom)
    and the shared vertex is a convex corner on the far side. The cut runs from the concave
    point straight on, along the slit (from the middle of the notch's mouth through its
    bottom, or along the bisector of its walls), to where the ray leaves the component, and
    ends at the contour point there that lies farthest along the ray (the shared tip).

    Parameters
    ----------
    flat : numpy.ndarray
        ``(n, 2)`` float64 contour.
    dfs : numpy.ndarray
        Convexity-defect rows ``(start, end, corner, depth × 256)`` (the 4 deepest are used).
    min_sep : int
        Smallest arc (contour points) between the two ends of a cut.

    Returns
    -------
    list of tuple
        ``(rank, i, j)``: a sort key (after every ordinary cut) and the contour indices.
    """
    n = len(flat)
    lo = flat.min(axis=0) - 1
    size = (flat.max(axis=0) - lo + 2).astype(np.int64)
    mask = np.zeros((int(size[1]), int(size[0])), dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(flat - lo).astype(np.int32).reshape(-1, 1, 2)], 1)
    reach = float(np.hypot(*size))
    steps = np.arange(1.0, reach, 0.5)
    out: list[_Cut] = []
    walls = max(3, min(10, n // 24))
    # the rays (mouth direction, then bisector, per defect), marched all at once
    origin: list[int] = []
    dirs: list[NDArray[np.float64]] = []
    for s_, e_, far, _depth in dfs[np.argsort(-dfs[:, 3])][:4].tolist():
        p = flat[far]
        u1 = flat[(far - walls) % n] - p
        u2 = flat[(far + walls) % n] - p
        bis = -(u1 / max(float(np.hypot(*u1)), 1e-9) + u2 / max(float(np.hypot(*u2)), 1e-9))
        mouth = p - 0.5 * (flat[s_] + flat[e_])
        for d in (mouth, bis):
            ln = float(np.hypot(*d))
            if ln >= 1e-6:
                origin.append(far)
                dirs.append(d / ln)
    if not dirs:
        return out
    start = flat[origin]  # (R, 2)
    unit = np.array(dirs)  # (R, 2)
    rays = start[:, None, :] + steps[None, :, None] * unit[:, None, :]  # (R, S, 2)
    rc = np.round(rays - lo).astype(np.int64)
    ok = (rc[..., 0] >= 0) & (rc[..., 1] >= 0) & (rc[..., 0] < size[0]) & (rc[..., 1] < size[1])
    inside = np.zeros(ok.shape, dtype=bool)
    inside[ok] = mask[rc[..., 1][ok], rc[..., 0][ok]] > 0
    leaves = ~inside
    # the last step inside: just before the first step outside (or the last step)
    lasts = np.where(leaves.any(axis=1), leaves.argmax(axis=1), len(steps)) - 1
    keep = np.nonzero(lasts >= 2)[0]
    if len(keep) == 0:
        return out
    lasts_k = lasts[keep]
    exits = rays[keep, lasts_k]  # (K, 2): the last point inside along each kept ray
    fars = np.asarray(origin)[keep]
    dist = np.sqrt(((flat[None, :, :] - exits[:, None, :]) ** 2).sum(axis=2))  # (K, n)
    arc = np.abs(np.arange(n)[None, :] - fars[:, None])
    arc = np.minimum(arc, n - arc)
    near = (dist <= np.maximum(3.0, 0.08 * steps[lasts_k])[:, None]) & (arc >= min_sep)
    rel = flat[None, :, :] - flat[fars][:, None, :]
    along = rel[..., 0] * unit[keep, 0, None] + rel[..., 1] * unit[keep, 1, None]
    best = np.where(near, along, -np.inf).argmax(axis=1)
    for i, j, last, hit in zip(fars.tolist(), best.tolist(), lasts_k.tolist(), near.any(axis=1).tolist(), strict=True):
        if hit:
            out.append((100.0 + float(steps[last]), i, j))
    return out
