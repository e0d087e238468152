"""Synthetic camera frames of Order Type Tags, for decoder tests and benchmarks.

A pinhole camera (:mod:`ottag_db.printing.camera`, re-exported here) looks at tags at random
poses (:func:`random_pose`, :func:`pose_homography`); :func:`render_scene` draws them
supersampled into a grey frame and degrades it (illumination gradient, blur, noise, JPEG);
:func:`random_scene` picks tags, poses and degradations at random. Every frame comes with its
ground truth: the image position of every point of every tag.

A tag is drawn from its points, triangles and placement (:class:`DrawableTag`); where those
come from (a database, a point file) is the caller's business.

Conventions: image coordinates are pixels with the origin at the centre of the top-left pixel,
x right, y down. The *data area* is the black square of a normal-polarity tag, ``[0, 1]²`` in
data-area units (x right, y down); a placement is the ``(2, 3)`` affine map from grid (file)
coordinates to data-area units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import maximal_perturbation
from ottag_db.core.types import POLARITIES, QUIET_ZONE, Polarity
from ottag_db.errors import ExportError, UsageError
from ottag_db.printing.camera import camera_matrix, pose_homography, project, random_pose

__all__ = [
    "MARGIN_PX",
    "MIN_IMAGE_MARGIN_PX",
    "MIN_SIDE_PX",
    "PLACEMENT",
    "QUIET_ZONE",
    "SUPERSAMPLING",
    "DrawableTag",
    "Scene",
    "TagSpec",
    "camera_matrix",
    "drawable_from_file_order",
    "min_width_px",
    "pose_homography",
    "posed_spec",
    "project",
    "random_pose",
    "random_scene",
    "render_scene",
]

F64 = NDArray[np.float64]

#: A fixed placement of the 0 … 255 grid: u = 0.1 + 0.8 · g / 255 (x and y), for tags drawn
#: without the project's placement.
PLACEMENT: F64 = np.array([[0.8 / 255, 0.0, 0.1], [0.0, 0.8 / 255, 0.1]])
#: Supersampling factor of the renderer: polygons are filled at this many times the frame
#: resolution and reduced with area averaging (exact anti-aliasing up to 1/16 px).
SUPERSAMPLING = 4
#: Frontal point-to-line margin (px) the random scenes give every tag at least.
MARGIN_PX = 4.5
#: Smallest point-to-line margin (px) of a random scene's tag as seen in the image. A strong
#: tilt seen in perspective squeezes part of a tag by more than cos(tilt), so this is checked
#: on the projected points; below it tags leave the decoder's design envelope (margins under
#: 1 px cannot be read at all).
MIN_IMAGE_MARGIN_PX = 0.7 * MARGIN_PX
#: Shortest side (px) of a random scene's data area as seen in the image.
MIN_SIDE_PX = 40.0
_UNIT_SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
# Printed tag side (m) of posed_spec's scenes; only its ratio to the distance matters.
_POSED_SIZE = 0.1


@dataclass(frozen=True)
class DrawableTag:
    """How a tag is drawn: its points, triangles and placement.

    Attributes
    ----------
    lambda_text : str
        Canonical ID ``k:digits`` of the tag's order type.
    points : ndarray, shape (k, 2), float64
        Grid coordinates in canonical label order (row ``l`` is the point with label ``l``),
        so the scene's ground truth lines up with a decoder's points.
    triangles : tuple of (int, int, int)
        Filled triangles, as indices into ``points``.
    placement : ndarray, shape (2, 3), float64
        Affine map from grid coordinates to data-area units.
    printed_mp_unit : float
        MP of the placed points, in data-area units (decides how small the tag may be drawn).
    """

    lambda_text: str
    points: F64
    triangles: tuple[tuple[int, int, int], ...]
    placement: F64
    printed_mp_unit: float

    @property
    def k(self) -> int:
        """Number of points."""
        return int(self.points.shape[0])


def drawable_from_file_order(
    lambda_text: str,
    points: ArrayLike,
    labeling: Sequence[int],
    triangles: Sequence[Sequence[int]],
    placement: ArrayLike,
    printed_mp_unit: float,
) -> DrawableTag:
    """A :class:`DrawableTag` from a realization stored in file order (as a database holds it).

    Parameters
    ----------
    lambda_text : str
        Canonical ID of the order type.
    points : array_like, shape (k, 2)
        Grid coordinates in file order.
    labeling : sequence of int
        ``labeling[l]`` is the file index of the point with canonical label ``l``.
    triangles : sequence of (int, int, int)
        Layout triangles as file indices.
    placement : array_like, shape (2, 3)
        Affine map grid → data-area units (independent of the point order).
    printed_mp_unit : float
        MP of the placed points, data-area units.

    Returns
    -------
    DrawableTag
        Points in canonical label order, triangles re-indexed to match.
    """
    pts = np.asarray(points, dtype=np.float64)
    order = [int(i) for i in labeling]
    if sorted(order) != list(range(len(pts))):
        raise UsageError(f"labeling {order} is not a permutation of the {len(pts)} point indices")
    label_of = {file_index: label for label, file_index in enumerate(order)}
    tris = tuple((label_of[int(a)], label_of[int(b)], label_of[int(c)]) for a, b, c in triangles)
    return DrawableTag(lambda_text, pts[order], tris, np.asarray(placement, dtype=np.float64), float(printed_mp_unit))


@dataclass(frozen=True)
class TagSpec:
    """One tag to draw into a frame.

    Attributes
    ----------
    points : ndarray, shape (k, 2), float64
        Grid coordinates; the ground truth is reported in this order.
    triangles : tuple of (int, int, int)
        Filled triangles, as indices into ``points``.
    homography : ndarray, shape (3, 3), float64
        Map from data-area units to image pixels.
    polarity : {"normal", "inverted"}
        Normal: white quiet zone, black data area, white triangles; inverted swaps the tones.
    quiet : float
        Quiet-zone width, data-area units.
    lambda_text : str
        Canonical ID of the order type (ground truth only; empty when unknown).
    placement : ndarray, shape (2, 3), float64
        Affine map grid → data-area units.
    """

    points: F64
    triangles: tuple[tuple[int, int, int], ...]
    homography: F64
    polarity: Polarity = "normal"
    quiet: float = QUIET_ZONE
    lambda_text: str = ""
    placement: F64 = field(default_factory=lambda: PLACEMENT.copy())


@dataclass(frozen=True)
class Scene:
    """A rendered frame and the ground truth of its tags.

    Attributes
    ----------
    image : ndarray, shape (h, w), uint8
        The grey frame.
    tags : tuple of TagSpec
        The tags drawn, in drawing order.
    truth_points : tuple of ndarray, each shape (k, 2), float64
        Image position (px) of every point of ``tags[i]``, in the order of its ``points``.
    """

    image: NDArray[np.uint8]
    tags: tuple[TagSpec, ...]
    truth_points: tuple[F64, ...]


def _fill(canvas: NDArray[np.uint8], poly_img: F64, value: int) -> None:
    # Frame pixel centres map to supersampled pixel centres; 4 fractional bits (× 16).
    ss = (poly_img * SUPERSAMPLING + (SUPERSAMPLING - 1) / 2) * 16
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
    """Draw tags, and other patches, into a grey frame and degrade it.

    Polygons are filled at :data:`SUPERSAMPLING` × the resolution and reduced by area
    averaging. Then, in this order: a multiplicative linear illumination gradient in a random
    direction, Gaussian blur, Gaussian noise, JPEG compression.

    Parameters
    ----------
    shape : (int, int)
        Frame height and width, px.
    tags : sequence of TagSpec
        Tags to draw (quiet zone, data area, triangles), in this order.
    rng : numpy.random.Generator
        Draws the gradient direction and the noise.
    white, black, background : int
        Grey levels of the tag's light and dark tones and of the empty frame.
    gradient : float
        Relative strength of the illumination gradient (0 = none): the grey level is
        multiplied by a factor from ``1 − gradient`` to 1 across the frame.
    blur : float
        Gaussian blur σ, px (0 = none).
    noise : float
        Gaussian noise σ, grey levels (0 = none).
    jpeg : int or None
        JPEG quality 0 … 100, or None for no compression.
    extra : sequence of (ndarray, ndarray)
        Grey patches (e.g. other markers) with the homography from the patch's unit square to
        the image, drawn under the tags.

    Returns
    -------
    Scene
        The frame and, per tag, the image positions of its points.
    """
    if jpeg is not None and not 0 <= jpeg <= 100:
        raise UsageError(f"JPEG quality must be 0 … 100, got {jpeg}")
    h, w = shape
    ss = SUPERSAMPLING
    canvas = np.full((h * ss, w * ss), background, dtype=np.uint8)
    frame_to_ss = np.array([[ss, 0, (ss - 1) / 2], [0, ss, (ss - 1) / 2], [0, 0, 1.0]])
    for patch, hu in extra:
        ph, pw = patch.shape[:2]
        unit_to_patch = np.array([[pw, 0, -0.5], [0, ph, -0.5], [0, 0, 1.0]])
        m = frame_to_ss @ hu @ np.linalg.inv(unit_to_patch)
        warped = cv2.warpPerspective(patch, m, (w * ss, h * ss), flags=cv2.INTER_LINEAR, borderValue=0)
        inside = cv2.warpPerspective(np.full_like(patch, 255), m, (w * ss, h * ss), flags=cv2.INTER_NEAREST)
        canvas[inside > 0] = warped[inside > 0]
    truth: list[F64] = []
    for t in tags:
        fg_val, bg_val = (white, black) if t.polarity == "normal" else (black, white)
        q = t.quiet
        quiet = np.array([[-q, -q], [1 + q, -q], [1 + q, 1 + q], [-q, 1 + q]])
        _fill(canvas, project(t.homography, quiet), fg_val)
        _fill(canvas, project(t.homography, _UNIT_SQUARE), bg_val)
        unit = np.c_[t.points, np.ones(len(t.points))] @ t.placement.T
        img_pts = project(t.homography, unit)
        for tri in t.triangles:
            _fill(canvas, img_pts[list(tri)], fg_val)
        truth.append(img_pts)
    img = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
    if gradient:
        ang = rng.uniform(0, 2 * math.pi)
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        ramp = (np.cos(ang) * (xx / w - 0.5) + np.sin(ang) * (yy / h - 0.5)) * 2
        img *= 1.0 - 0.5 * gradient + 0.5 * gradient * ramp
    if blur > 0:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), blur), dtype=np.float32)
    if noise > 0:
        img += np.asarray(rng.normal(0, noise, img.shape), dtype=np.float32)
    out: NDArray[np.uint8] = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    if jpeg is not None:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg)])
        if not ok:
            raise ExportError("OpenCV could not JPEG-encode the frame")
        decoded = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
        if decoded is None:
            raise ExportError("OpenCV could not decode its own JPEG frame")
        out = np.asarray(decoded, dtype=np.uint8)
    return Scene(out, tuple(tags), tuple(truth))


def posed_spec(
    tag: DrawableTag,
    rng: np.random.Generator,
    width_px: float,
    tilt_deg: float,
    polarity: Polarity = "normal",
    center_px: tuple[float, float] = (320, 240),
) -> TagSpec:
    """A tag at a random pose of the 640×480 camera with f = 700 px.

    Parameters
    ----------
    tag : DrawableTag
        The tag to draw.
    rng : numpy.random.Generator
        Draws the in-plane rotation and tilt axis (see :func:`random_pose`).
    width_px : float
        Frontal-equivalent side of the data area, px.
    tilt_deg : float
        Tilt, degrees.
    polarity : {"normal", "inverted"}
        Tone of the tag.
    center_px : (float, float)
        Image position of the data area's centre, px.

    Returns
    -------
    TagSpec
        The tag with its homography.
    """
    if polarity not in POLARITIES:
        raise UsageError(f"polarity must be one of {', '.join(POLARITIES)}, got {polarity!r}")
    k_mat = camera_matrix()
    r_mat, t = random_pose(rng, k_mat, _POSED_SIZE, width_px, tilt_deg, center_px)
    hom = pose_homography(k_mat, r_mat, t, _POSED_SIZE)
    return TagSpec(tag.points, tag.triangles, hom, polarity, lambda_text=tag.lambda_text, placement=tag.placement)


def min_width_px(mp_unit: float) -> float:
    """Smallest frontal data-area width (px) the random scenes use for a tag.

    Chosen so that the point-to-line margin 2 · MP spans at least :data:`MARGIN_PX` px, and
    never below 50 px.

    Parameters
    ----------
    mp_unit : float
        MP of the placed points, data-area units.

    Returns
    -------
    float
        ``max(50, MARGIN_PX / (2 · mp_unit))``, px.
    """
    return max(50.0, MARGIN_PX / (2.0 * mp_unit))


def random_scene(
    rng: np.random.Generator,
    tags: Sequence[DrawableTag],
    *,
    n_tags: int = 2,
    shape: tuple[int, int] = (480, 640),
    max_width: float = 250.0,
    max_tilt: float = 80.0,
    jpeg: int | None = 70,
) -> Scene:
    """A frame with up to ``n_tags`` tags drawn at random from ``tags``, both polarities.

    Width (frontal-equivalent data-area side) is uniform in ``[w_min, max(1.6 · w_min,
    max_width)]`` px with ``w_min = min_width_px(printed MP)``; tilt is uniform in
    ``[0, max_tilt]`` degrees, narrowed so that ``width · cos(tilt) >= max(40, 0.7 · w_min)``
    (the foreshortened side); the position is uniform in the central 70 % of the frame. A pose
    is kept only if, in the image, the data area's sides are at least :data:`MIN_SIDE_PX` and
    the points' margin (2 · MP) at least :data:`MIN_IMAGE_MARGIN_PX`, the quiet zone lies inside
    the frame and overlaps no other; a tag that finds no such pose in 60 tries is left out.
    Degradations: gradient ∈ [0, 0.5], blur σ ∈ [0, 1] px, noise σ ∈ [0, 5] grey levels, JPEG
    at quality ``jpeg``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of every random choice (the same seed gives the same frame).
    tags : sequence of DrawableTag
        Tags to choose from (uniformly).
    n_tags : int
        Tags to place.
    shape : (int, int)
        Frame height and width, px; the camera has f = 700 px.
    max_width : float
        Upper end of the width range, px.
    max_tilt : float
        Largest tilt, degrees.
    jpeg : int or None
        JPEG quality, or None for none.

    Returns
    -------
    Scene
        The frame and its ground truth.
    """
    if not tags:
        raise UsageError("random_scene needs at least one tag to draw")
    h, w = shape
    k_mat = camera_matrix(700.0, w, h)
    specs: list[TagSpec] = []
    boxes: list[tuple[float, float, float, float]] = []
    q = QUIET_ZONE
    quiet_corners = np.array([[-q, -q], [1 + q, -q], [1 + q, 1 + q], [-q, 1 + q]])
    for _ in range(n_tags):
        for _attempt in range(60):
            tag = tags[int(rng.integers(len(tags)))]
            w_min = min_width_px(tag.printed_mp_unit)
            width = rng.uniform(w_min, max(1.6 * w_min, max_width))
            need = max(40.0, 0.7 * w_min)
            if width * math.cos(math.radians(max_tilt)) >= need:
                tilt = rng.uniform(0, max_tilt)
            else:
                tilt = rng.uniform(0, min(max_tilt, math.degrees(math.acos(min(1.0, need / width)))))
            center = (rng.uniform(0.15 * w, 0.85 * w), rng.uniform(0.15 * h, 0.85 * h))
            r_mat, t = random_pose(rng, k_mat, _POSED_SIZE, width, tilt, center)
            hom = pose_homography(k_mat, r_mat, t, _POSED_SIZE)
            qc = project(hom, quiet_corners)
            # Both ends of the quiet zone's diagonal must lie in front of the camera.
            diagonal = np.array([[-q, -q, 0], [1 + q, 1 + q, 0]]) * _POSED_SIZE
            depth = (r_mat @ diagonal.T + t[:, None])[2]
            if (depth <= 0).any():
                continue
            square = project(hom, _UNIT_SQUARE)
            sides = np.linalg.norm(square - np.roll(square, 1, axis=0), axis=1)
            placed = np.c_[tag.points, np.ones(tag.k)] @ tag.placement.T
            if sides.min() < MIN_SIDE_PX or 2 * maximal_perturbation(project(hom, placed)) < MIN_IMAGE_MARGIN_PX:
                continue
            box = (qc[:, 0].min() - 4, qc[:, 1].min() - 4, qc[:, 0].max() + 4, qc[:, 1].max() + 4)
            if box[0] < 2 or box[1] < 2 or box[2] > w - 3 or box[3] > h - 3:
                continue
            if any(not (box[2] < b[0] or b[2] < box[0] or box[3] < b[1] or b[3] < box[1]) for b in boxes):
                continue
            pol: Polarity = "normal" if rng.random() < 0.5 else "inverted"
            specs.append(TagSpec(tag.points, tag.triangles, hom, pol, q, tag.lambda_text, tag.placement))
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
