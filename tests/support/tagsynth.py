"""Synthetic Order Type Tag scenes for the decoder/pose tests and benchmarks (test helper)."""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import canonical_batch
from ottag_db.core.geometry import maximal_perturbations
from ottag_db.core.lookup import LookupEntry, MemoryLookup

__all__ = [
    "PLACEMENT",
    "SS",
    "Drawable",
    "Scene",
    "TagSpec",
    "aichholzer_dir",
    "camera_matrix",
    "drawable",
    "layout_triangles",
    "min_width_px",
    "pose_homography",
    "random_pose",
    "random_scene",
    "reference_lookup",
    "render_scene",
]

F64 = NDArray[np.float64]

#: File (grid) coordinates → data-area unit square: u = 0.1 + 0.8 * g / 255 (x and y).
PLACEMENT: F64 = np.array([[0.8 / 255, 0.0, 0.1], [0.0, 0.8 / 255, 0.1]])
#: Supersampling factor of the renderer (polygons drawn at SS× then INTER_AREA down).
SS = 4


def aichholzer_dir() -> Path | None:
    """Folder of the reference files from $OTTAG_AICHHOLZER_DIR, or None."""
    d = os.environ.get("OTTAG_AICHHOLZER_DIR")
    if not d or not Path(d, "otypes05.b08").exists():
        return None
    return Path(d)


def reference_lookup(folder: Path, ks: Sequence[int] = (5, 6, 7, 8)) -> tuple[MemoryLookup, list[dict[str, object]]]:
    """MemoryLookup of the reference sets and their mirrors (x → 255 − x).

    Returns the lookup and a list of drawable records ``{"lambda", "points" (canonical order),
    "mp", "k"}``, one per stored realization. Achiral order types hold both the set and its
    mirror as realizations.
    """
    from ottag_db.files.pointfile import read_point_file

    entries: dict[str, LookupEntry] = {}
    records: list[dict[str, object]] = []
    next_id = 1
    for k in ks:
        pts = np.asarray(read_point_file(folder / f"otypes{k:02d}.b08"), dtype=np.float64)
        mir = pts.copy()
        mir[..., 0] = 255 - mir[..., 0]
        for batch in (pts, mir):
            cb = canonical_batch(batch)
            texts = cb.texts()
            mps = maximal_perturbations(batch)
            for b, text in enumerate(texts):
                real = batch[b][cb.labelings[b]]
                old = entries.get(text)
                if old is None:
                    entries[text] = LookupEntry(
                        lambda_text=text,
                        k=k,
                        order_type_id=next_id,
                        unique_min=bool(cb.minimal_orderings[b] == 1),
                        realizations=(real,),
                        tag=next_id,
                    )
                    next_id += 1
                else:
                    entries[text] = LookupEntry(
                        old.lambda_text, k, old.order_type_id, old.unique_min,
                        (*old.realizations, real), old.tag,
                    )  # fmt: skip
                records.append({"lambda": text, "points": real, "mp": float(mps[b]), "k": k})
    return MemoryLookup(entries.values()), records


# ---------------------------------------------------------------------- layout
def _seg_dist(p: F64, a: F64, b: F64) -> float:
    d = b - a
    t = float(np.clip(np.dot(p - a, d) / max(np.dot(d, d), 1e-12), 0, 1))
    return float(np.linalg.norm(p - (a + t * d)))


def _segs_cross(a: F64, b: F64, c: F64, d: F64) -> bool:
    def orient(p: F64, q: F64, r: F64) -> float:
        return float((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    return orient(a, b, c) * orient(a, b, d) < 0 and orient(c, d, a) * orient(c, d, b) < 0


def _point_tri_dist(p: F64, q: int, t: tuple[int, int, int]) -> float:
    """Distance from point ``q`` to the sides of triangle ``t`` (indices into ``p``)."""
    return min(_seg_dist(p[q], p[a], p[b]) for a, b in itertools.combinations(t, 2))


def _inside(q: F64, tri: F64) -> bool:
    s = [
        (tri[(i + 1) % 3, 0] - tri[i, 0]) * (q[1] - tri[i, 1]) - (tri[(i + 1) % 3, 1] - tri[i, 1]) * (q[0] - tri[i, 0])
        for i in range(3)
    ]
    return all(v > 0 for v in s) or all(v < 0 for v in s)


def _altitude(p: F64, t: tuple[int, int, int]) -> float:
    a, b, c = p[list(t)]
    area2 = abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    longest = max(np.linalg.norm(a - b), np.linalg.norm(b - c), np.linalg.norm(c - a))
    return float(area2 / longest)


def _compatible(p: F64, t1: tuple[int, int, int], t2: tuple[int, int, int], gap: float) -> bool:
    shared = set(t1) & set(t2)
    if len(shared) >= 2:
        return False
    for a, b in itertools.combinations(t1, 2):
        for c, d in itertools.combinations(t2, 2):
            if len({a, b} & {c, d}) == 0 and _segs_cross(p[a], p[b], p[c], p[d]):
                return False
    for v in t1:
        if v not in shared and _inside(p[v], p[list(t2)]):
            return False
    for v in t2:
        if v not in shared and _inside(p[v], p[list(t1)]):
            return False
    # clearance between the triangles away from a shared vertex
    for v in t1:
        if v in shared:
            continue
        for a, b in itertools.combinations(t2, 2):
            if _seg_dist(p[v], p[a], p[b]) < gap:
                return False
    for v in t2:
        if v in shared:
            continue
        for a, b in itertools.combinations(t1, 2):
            if _seg_dist(p[v], p[a], p[b]) < gap:
                return False
    if shared:
        s = p[next(iter(shared))]

        def sector(t: tuple[int, int, int]) -> tuple[float, float]:
            o = [q for q in t if q not in shared]
            angs = sorted(math.atan2(p[q][1] - s[1], p[q][0] - s[0]) for q in o)
            if angs[1] - angs[0] > math.pi:
                angs = [angs[1], angs[0] + 2 * math.pi]
            return angs[0], angs[1]

        a0, a1 = sector(t1)
        b0, b1 = sector(t2)
        for off in (-2 * math.pi, 0.0, 2 * math.pi):
            lo, hi = b0 + off, b1 + off
            if not (hi + math.radians(20) <= a0 or lo >= a1 + math.radians(20)):
                return False
    return True


def layout_triangles(points: F64, gap: float = 8.0) -> list[tuple[int, int, int]]:
    """A non-overlapping triangle layout covering every point (test helper).

    Triangles contain no other point, share at most a vertex (with a 20° angular gap at the
    shared vertex), keep ``gap`` grid units from other triangles' sides, and a search over
    covers with the fewest triangles maximises the smallest altitude. Falls back to a smaller
    gap when nothing fits.
    """
    p = np.asarray(points, dtype=np.float64)
    k = len(p)
    cands = []
    for t in itertools.combinations(range(k), 3):
        tri = p[list(t)]
        if any(_inside(p[q], tri) for q in range(k) if q not in t):
            continue
        if any(_point_tri_dist(p, q, t) < gap for q in range(k) if q not in t):
            continue
        cands.append((t, _altitude(p, t)))
    cands.sort(key=lambda c: -c[1])
    best: tuple[float, list[tuple[int, int, int]]] = (-1.0, [])
    limit = math.ceil(k / 3) + 1

    def search(chosen: list[tuple[int, int, int]], covered: set[int], score: float) -> None:
        nonlocal best
        if len(covered) == k:
            key = score - 1000.0 * len(chosen)
            if key > best[0] - 1000.0 * len(best[1]) or not best[1]:
                best = (score, list(chosen))
            return
        if len(chosen) >= limit or (score <= best[0] and best[1] and len(chosen) >= len(best[1])):
            return
        first = min(set(range(k)) - covered)
        for t, alt in cands:
            if first not in t or min(score, alt) <= (best[0] if best[1] else -1):
                continue
            if all(_compatible(p, t, o, gap) for o in chosen):
                chosen.append(t)
                search(chosen, covered | set(t), min(score, alt))
                chosen.pop()

    search([], set(), math.inf)
    if not best[1]:
        if gap > 1:
            return layout_triangles(p, gap / 2)
        raise ValueError("no triangle layout found")
    return best[1]


# ---------------------------------------------------------------------- scenes
def camera_matrix(f: float = 700.0, w: int = 640, h: int = 480) -> F64:
    """Pinhole intrinsics with the principal point at the image centre (pixel-centre origin)."""
    return np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])


def pose_homography(k_mat: F64, r_mat: F64, t: F64, size: float) -> F64:
    """Homography data-area unit square → image for a tag of side ``size`` at pose (R, t)."""
    h = k_mat @ np.c_[r_mat[:, 0] * size, r_mat[:, 1] * size, t]
    out: F64 = h / h[2, 2]
    return out


def _rot(axis: F64, ang: float) -> F64:
    r, _ = cv2.Rodrigues(np.asarray(axis, dtype=np.float64).reshape(3, 1) * ang)
    out: F64 = r
    return out


def random_pose(
    rng: np.random.Generator,
    k_mat: F64,
    size: float,
    width_px: float,
    tilt_deg: float,
    center_px: tuple[float, float],
) -> tuple[F64, F64]:
    """(R, t) of a tag of side ``size`` seen ``width_px`` wide (frontal-equivalent) at a tilt.

    Tag frame: x right, y down along the printed tag, z = x × y into the tag; frontal is R = I.
    """
    f = float(k_mat[0, 0])
    z = f * size / width_px
    phi = rng.uniform(0, 2 * math.pi)
    psi = rng.uniform(0, 2 * math.pi)
    r = _rot(np.array([math.cos(phi), math.sin(phi), 0.0]), math.radians(tilt_deg)) @ _rot(np.array([0, 0, 1.0]), psi)
    c = z * np.linalg.solve(k_mat, np.array([center_px[0], center_px[1], 1.0]))
    t = c - r @ np.array([size / 2, size / 2, 0.0])
    return r, t


@dataclass
class TagSpec:
    """One tag to draw: canonical-order points (grid), triangles, unit→image homography."""

    points: F64
    triangles: list[tuple[int, int, int]]
    homography: F64
    polarity: str = "normal"
    quiet: float = 0.25
    lambda_: str = ""
    placement: F64 = field(default_factory=lambda: PLACEMENT.copy())


@dataclass
class Scene:
    """A rendered frame and the ground truth of its tags (image points in canonical order)."""

    image: NDArray[np.uint8]
    tags: list[TagSpec]
    truth_points: list[F64] = field(default_factory=list)


def _proj(h: F64, pts: F64) -> F64:
    ph = np.c_[pts, np.ones(len(pts))] @ h.T
    out: F64 = ph[:, :2] / ph[:, 2:3]
    return out


def _fill(canvas: NDArray[np.uint8], poly_img: F64, value: int) -> None:
    ss = (poly_img * SS + (SS - 1) / 2) * 16
    cv2.fillPoly(canvas, [np.round(ss).astype(np.int32).reshape(-1, 1, 2)], int(value), cv2.LINE_8, 4)


def render_scene(
    shape: tuple[int, int],
    tags: Sequence[TagSpec],
    rng: np.random.Generator,
    *,
    white: int = 235,
    black: int = 30,
    background: int = 200,
    gradient: float = 0.0,
    blur: float = 0.0,
    noise: float = 0.0,
    jpeg: int | None = None,
    extra: Sequence[tuple[NDArray[np.uint8], F64]] = (),
) -> Scene:
    """Draw tags (and ``extra`` (image, unit→image homography) patches) into a grey frame.

    Polygons are filled at 4× and reduced with INTER_AREA (exact anti-aliasing). Then a
    multiplicative linear illumination gradient of relative strength ``gradient``, a Gaussian
    blur σ = ``blur`` px, Gaussian noise σ = ``noise`` grey levels and JPEG at quality
    ``jpeg`` are applied.
    """
    h, w = shape
    canvas = np.full((h * SS, w * SS), background, dtype=np.uint8)
    scene = Scene(np.zeros((h, w), np.uint8), list(tags))
    s_to_ss = np.array([[SS, 0, (SS - 1) / 2], [0, SS, (SS - 1) / 2], [0, 0, 1.0]])
    for patch, hu in extra:
        ph, pw = patch.shape[:2]
        unit_to_patch = np.array([[pw, 0, -0.5], [0, ph, -0.5], [0, 0, 1.0]])
        m = s_to_ss @ hu @ np.linalg.inv(unit_to_patch)
        warped = cv2.warpPerspective(patch, m, (w * SS, h * SS), flags=cv2.INTER_LINEAR, borderValue=0)
        maskw = cv2.warpPerspective(np.full_like(patch, 255), m, (w * SS, h * SS), flags=cv2.INTER_NEAREST)
        canvas[maskw > 0] = warped[maskw > 0]
    for t in tags:
        fg_val, bg_val = (white, black) if t.polarity == "normal" else (black, white)
        q = t.quiet
        quiet = np.array([[-q, -q], [1 + q, -q], [1 + q, 1 + q], [-q, 1 + q]])
        square = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
        _fill(canvas, _proj(t.homography, quiet), fg_val)
        _fill(canvas, _proj(t.homography, square), bg_val)
        unit = np.c_[t.points, np.ones(len(t.points))] @ t.placement.T
        img_pts = _proj(t.homography, unit)
        for tri in t.triangles:
            _fill(canvas, img_pts[list(tri)], fg_val)
        scene.truth_points.append(img_pts)
    img = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
    if gradient:
        ang = rng.uniform(0, 2 * math.pi)
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        ramp = (np.cos(ang) * (xx / w - 0.5) + np.sin(ang) * (yy / h - 0.5)) * 2
        img *= 1.0 - 0.5 * gradient + 0.5 * gradient * ramp
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur)
    if noise > 0:
        img += rng.normal(0, noise, img.shape).astype(np.float32)
    out = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    if jpeg is not None:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg)])
        assert ok
        out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    scene.image = out
    return scene


#: Frontal point-to-line margin (px) the random scenes give every tag at least.
MARGIN_PX = 4.5


@dataclass
class Drawable:
    """How a record is drawn: the project's layout and placement, and the placed MP."""

    triangles: list[tuple[int, int, int]]
    placement: F64
    mp_unit: float  # MP of the placed points in data-area units


def drawable(rec: dict[str, object], cache: dict[bytes, Drawable]) -> Drawable:
    """Layout (``ottag_db.core.layout.compute_layout``) and placement (``ottag_db.printing.render.tag_placement``)."""
    from ottag_db.core.layout import compute_layout
    from ottag_db.core.placement import tag_placement

    pts = np.asarray(rec["points"], dtype=np.float64)
    key = pts.tobytes()
    if key not in cache:
        tris = [tuple(int(v) for v in t) for t in compute_layout(pts).triangles]
        aff = tag_placement(pts)
        unit = np.c_[pts, np.ones(len(pts))] @ aff.T
        cache[key] = Drawable(tris, aff, float(maximal_perturbations(unit[None])[0]))  # type: ignore[misc]
    return cache[key]


def posed_spec(
    rec: dict[str, object],
    rng: np.random.Generator,
    width_px: float,
    tilt_deg: float,
    polarity: str = "normal",
    cache: dict[bytes, Drawable] | None = None,
    center_px: tuple[float, float] = (320, 240),
) -> TagSpec:
    """A record drawn the project's way (layout, placement) at a random pose of the 640×480
    camera (f = 700): data area ``width_px`` wide frontally, tilted by ``tilt_deg``."""
    dr = drawable(rec, {} if cache is None else cache)
    k_mat = camera_matrix()
    r_mat, t = random_pose(rng, k_mat, 0.1, width_px, tilt_deg, center_px)
    hom = pose_homography(k_mat, r_mat, t, 0.1)
    return TagSpec(np.asarray(rec["points"]), dr.triangles, hom, polarity, placement=dr.placement)


def min_width_px(mp_unit: float) -> float:
    """Smallest frontal data-area width (px) used for a tag whose placed MP is ``mp_unit``.

    Chosen so the point-to-line margin 2·MP spans at least ``MARGIN_PX`` px, and never below
    50 px: ``max(50, MARGIN_PX / (2 · mp_unit))``.
    """
    return max(50.0, MARGIN_PX / (2.0 * mp_unit))


def random_scene(
    rng: np.random.Generator,
    records: Sequence[dict[str, object]],
    cache: dict[bytes, Drawable],
    *,
    n_tags: int = 2,
    shape: tuple[int, int] = (480, 640),
    max_width: float = 250.0,
    max_tilt: float = 80.0,
    jpeg: int | None = 70,
) -> Scene:
    """A frame with up to ``n_tags`` random tags of the records (both polarities).

    Tags are drawn with the project's layout and placement (:func:`drawable`). Width
    (frontal-equivalent data-area side, px) is uniform in ``[w_min, max(1.6·w_min,
    max_width)]`` with ``w_min = min_width_px(placed MP)``; tilt is uniform in ``[0, max_tilt]``
    degrees subject to ``width · cos(tilt) >= max(40, 0.7 · w_min)`` (foreshortened side);
    quiet zones lie inside the frame and do not overlap. Blur σ ∈ [0, 1] px, noise σ ∈ [0, 5],
    illumination gradient ∈ [0, 0.5], JPEG quality ``jpeg``.
    """
    h, w = shape
    k_mat = camera_matrix(700.0, w, h)
    specs: list[TagSpec] = []
    boxes: list[tuple[float, float, float, float]] = []
    for _ in range(n_tags):
        for _attempt in range(60):
            rec = records[int(rng.integers(len(records)))]
            pts = np.asarray(rec["points"], dtype=np.float64)
            dr = drawable(rec, cache)
            w_min = min_width_px(dr.mp_unit)
            width = rng.uniform(w_min, max(1.6 * w_min, max_width))
            need = max(40.0, 0.7 * w_min)
            if width * math.cos(math.radians(max_tilt)) >= need:
                tilt = rng.uniform(0, max_tilt)
            else:
                tilt = rng.uniform(0, min(max_tilt, math.degrees(math.acos(min(1.0, need / width)))))
            center = (rng.uniform(0.15 * w, 0.85 * w), rng.uniform(0.15 * h, 0.85 * h))
            r_mat, t = random_pose(rng, k_mat, 0.1, width, tilt, center)
            hom = pose_homography(k_mat, r_mat, t, 0.1)
            quiet = 0.25
            qc = _proj(
                hom, np.array([[-quiet, -quiet], [1 + quiet, -quiet], [1 + quiet, 1 + quiet], [-quiet, 1 + quiet]])
            )
            depth = (r_mat @ np.array([[-0.025, -0.025, 0], [0.125, 0.125, 0]]).T + t[:, None])[2]
            if (depth <= 0).any():
                continue
            box = (qc[:, 0].min() - 4, qc[:, 1].min() - 4, qc[:, 0].max() + 4, qc[:, 1].max() + 4)
            if box[0] < 2 or box[1] < 2 or box[2] > w - 3 or box[3] > h - 3:
                continue
            if any(not (box[2] < b[0] or b[2] < box[0] or box[3] < b[1] or b[3] < box[1]) for b in boxes):
                continue
            pol = "normal" if rng.random() < 0.5 else "inverted"
            specs.append(TagSpec(pts, dr.triangles, hom, pol, quiet, str(rec["lambda"]), dr.placement))
            boxes.append(box)
            break
    return render_scene(
        shape,
        specs,
        rng,
        gradient=rng.uniform(0, 0.5),
        blur=rng.uniform(0, 1.0),
        noise=rng.uniform(0, 5.0),
        jpeg=jpeg,
    )
