"""A candidate's blur, measured on its data area's sides.

Defocus and motion blur wash out what the reading at the frame's scale needs most: the sharp
tips of the triangles and the thin gaps between triangles that meet or lie close. Both are a
few pixels wide, so a blur of 2 px or more merges or erases them while the data area's sides,
long straight steps from the quiet zone's tone to the data area's, stay straight and centred.
Those sides measure the blur: across a step blurred by a Gaussian of σ px the grey level
rises with a slope of at most ``height / (σ √(2π))``. A candidate whose sides are blurred and
whose points did not read is read by model (:mod:`.model_match`), which compares the whole
printed tag with the frame and does not need the tips and gaps; reading it at a coarser scale
does not help, as the gaps shrink with the blur. The blurs a tag is then drawn with are
:mod:`.camera_blur`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from ottag_native.blur import side_blurs, side_samples

from ottag_db.decode.refine import lines_through, polygon_vertices
from ottag_db.decode.types import Quad

__all__ = [
    "BLURRED_MAX_MISFIT",
    "BLURRED_MAX_MISFIT_NOISY",
    "BLURRED_MIN_SIGMA",
    "NOMINAL_BLURS_PX",
    "EdgeBlur",
    "edge_blur",
]

_F64 = NDArray[np.float64]

#: Edge blur (σ of a Gaussian, frame px) from which a candidate the points did not read is
#: read by model. A sharp frame's sides measure 0.5–0.9 px (the lens's and the sensor's own
#: blur and antialiasing); from about 1.5 px the reading of the points loses triangles' tips
#: and gaps (a third of 8-point tags 98 px wide are lost at 1.5 px, nearly all at 2.5 px).
BLURRED_MIN_SIGMA = 1.2
#: The largest ratio of the blurs of a blurred tag's opposite sides. A defocus or a motion
#: blurs a small tag's opposite, nearly parallel sides alike (defocused tags measure within
#: 20 %; moving ones mostly within 50 %, up to 2× where a triangle near a side is smeared
#: across it), while the outline of clutter — a shadow, a brick, an animal's fur — is often
#: sharp on one side and soft on the opposite one (half the blurred quads of scikit-image's
#: photographs).
BLURRED_PAIR_RATIO = 2.0
#: How many standard errors of each side's measured blur (:attr:`EdgeBlur.errors`) the pair test
#: of :data:`BLURRED_PAIR_RATIO` allows: under sensor noise a side's nine samples scatter
#: (noise σ 6 on a step of 50 grey levels: ±0.3–0.8 px about a defocus of 2.5 px), and a
#: defocused tag's opposite sides then measured 1.5 and 3.0 px; clutter sharp on one side and
#: soft on the other measures each side consistently along it, so its errors stay small.
BLURRED_PAIR_ERRORS = 2.0
#: The opposite sides' pair test (:attr:`EdgeBlur.blurred`) leaves out a pair with a side whose
#: step is under this share of the candidate's (the median of its sides' steps): a long motion
#: smears a triangle near a side into its border, and the step left there, from the smear's
#: grey to the quiet zone, is a third to a half of the tag's (40–50 grey levels against 130–150
#: under 15–17 px motions); its slope measures the smear, not the motion (σ 1.8–1.9 where the
#: opposite side measured 5.7–6.0).
STEP_MIN_SHARE = 0.5
#: The largest local misfit (in units of the frame's contrast, as ``model_max_misfit``) of a
#: tag read by model when judged with the blur its sides measure. Drawn with the right blur,
#: the tag seen explains the frame nearly exactly: 0.02–0.04 under defocus of 2–4 px, up to
#: about 0.1 under motion blur (whose kernel the sides only approximate); a look-alike's
#: differing triangle, blurred as much, still leaves 0.14–0.24 — within the nominal limit,
#: which expects sharp triangles' full contrast. In a noisy frame the limit widens by what the
#: noise alone leaves (:attr:`~ottag_db.decode.model_align.Aligned.blurred_misfit_limit`).
BLURRED_MAX_MISFIT = 0.12
#: The widest the noise makes that limit. In a dim frame (contrast a quarter, noise σ 6) the
#: noise alone leaves 0.08–0.17 of a tag's contrast; the tag seen misfit its drawing by up to
#: 0.133 there, and a look-alike that would be read where the tag seen is taken out of the
#: lookup (its correlation and lead enough) by 0.177 and more: beyond this, the noise hides
#: the difference.
BLURRED_MAX_MISFIT_NOISY = 0.15
#: The smallest coarse match (:func:`~ottag_db.decode.model_budget.ranking_score`, on 16²
#: cells, where a blur of up to 4 px is under a cell of a 98 px data area) of a blurred
#: candidate read by model: a blurred tag's data area correlates 0.75–0.96 with its printed
#: tag there, the blurred quads of photographs (fur, bricks, text) 0.45–0.67; each reading by
#: model costs 20–40 ms. Taken also from the outline moved onto the sides' blurred steps
#: (:meth:`EdgeBlur.centred`), the better of the two.
BLURRED_MIN_RANKING = 0.7
#: The coarse match a blurred candidate needs when its sides' largest blur spans half a cell of
#: the ranking grid or more (between a quarter of a cell and half a cell, the floor falls
#: linearly from :data:`BLURRED_MIN_RANKING`): the ranking templates are sharp, and a blur of
#: half a cell (its width at half maximum, 2.35 σ, more than a cell) mixes each cell's print
#: with its neighbours'. The sides also measure a motion short (its step is a straight ramp, and
#: the steepest point, where the ramp's height is taken, lies anywhere along it): tags 80–100 px
#: wide moved by 15–17 px measure σ 2.7–4.4 px (0.5–0.9 cells) and correlate 0.6–0.7 with their
#: printed tag; the budget of readings by model still bounds what the lower floor costs on
#: clutter.
BLURRED_MIN_RANKING_SMEARED = 0.6
#: The smallest correlation with the nominal drawing (the first of :data:`NOMINAL_BLURS_PX`)
#: for which a blurred candidate's aligned tags are judged again with its measured blur: a
#: tag defocused by up to 4 px or moved by up to 15 px still correlates 0.8–0.96 with its
#: nominal drawing, one 80–90 px wide moved by 17 px 0.73–0.75, while most blurred quads of
#: clutter correlate less with every tag, and the judging again costs a drawing per blur and
#: aligned tag.
BLURRED_MIN_NOMINAL_CORRELATION = 0.7
#: The smallest data area, in blur widths (side / :attr:`EdgeBlur.width`), judged with its
#: measured blur: an 8-point tag's narrowest triangles and gaps are about a twelfth of its side,
#: and a blur of that width in every direction erases them, leaving nothing that tells tags
#: apart; candidates that small are mostly pieces of a tag's own triangles. A motion erases
#: only what lies across it (its sides along it stay sharp, and so do the triangles' edges
#: along it), hence the width over all directions.
BLURRED_MIN_SIDE = 12.0
#: Samples of a side's profile: where along the side (fractions; the corners are left out,
#: a corner's two sides bend the step there) and how far across it (px of the frame per σ
#: of the largest blur measured, in steps of half a pixel).
_ALONG = np.linspace(0.2, 0.8, 9)
#: Each sample of a side's profile is the mean of parallel profiles this far apart along the
#: side (frame px): the side is straight there, so they hold the same step, and their mean
#: keeps its blur while it divides the sensor noise. A single profile's steepest slope is
#: steepened by the noise: in a dim frame (noise σ 6 on a step of 45 grey levels) the sides
#: of a tag moved by 7 px measured σ 0.8–1.3 px against 1.3–2.0 without the noise, under
#: :data:`BLURRED_MIN_SIGMA`.
_ALONG_SPREAD = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])
#: Gaussian σ (frame px) of the blurs of a camera in focus and at rest: a tag is drawn with
#: these when judged by model (:func:`~ottag_db.decode.model_align.judge`), and the optics'
#: own blur under a motion blur is taken as the middle one.
NOMINAL_BLURS_PX = (0.45, 0.7, 1.0)
#: The largest move of a side onto its step's midpoint (:meth:`EdgeBlur.centred`), as a
#: fraction of the data area's side: a threshold's outline of a data area blurred by up to
#: 4 px lies within a few percent of it; a larger offset is a triangle's edge, not the side's.
_MAX_OFFSET = 0.08
_ACROSS_MAX = 14.0
_ACROSS_STEP = 0.5
#: The Gaussian (σ, px) that smooths a profile before its steepest slope is taken, and is
#: then taken out of the measured blur in quadrature: sensor noise of 6 grey levels on a step
#: of 50 made the slopes of half-pixel steps a third too steep (a defocus of 2.5 px measured
#: 1.7) when smoothed by half a pixel; smoothed by one it measures 2.3, sharp sides still
#: under 1 px.
_SMOOTHING_PX = 1.0
#: The smallest height (grey levels) of a sample's step that measures the side's blur (where a
#: triangle touches the side, or a long motion smeared one into it, there is little or no step
#: from the quiet zone): 20, or :data:`STEP_MIN_SHARE` of the median height of the candidate's
#: samples where that is less, but not under :data:`_NOISE_HEIGHT`. A dim frame's steps are
#: 25–45 grey levels, and under sensor noise the steepest point wanders along a blurred ramp,
#: scattering a sample's height by ±10 (noise σ 6 on a defocus of 2.5 px: a side's nine samples
#: measured 17–33), so a fixed 20 left sides unmeasured.
_MIN_HEIGHT = 20.0
#: The height (grey levels) under which a sample shows no step at all: sensor noise of σ 6,
#: averaged over the five profiles of a sample and smoothed, leaves heights of 2 in the median
#: on a flat region, under 9 in 99 samples of 100 (a photograph's smooth sky or page: 1–7).
_NOISE_HEIGHT = 10.0


@dataclass(frozen=True)
class EdgeBlur:
    """The blur measured across a candidate's four sides.

    Attributes
    ----------
    sides : tuple of float
        σ (frame px) per side, side ``i`` from corner ``i`` to corner ``i + 1``; NaN where too
        few samples showed a step.
    normals : numpy.ndarray
        ``(4, 2)`` the sides' unit normals.
    offsets : tuple of float
        Per side, how far (frame px, along its outward normal) the step's midpoint lies from
        the side; NaN where the side's blur is.
    errors : tuple of float
        Per side, the standard error (frame px) of its blur, from the scatter of its samples
        (1.25 × their interquartile range / 1.35 / √count); NaN where the side's blur is.
    steps : tuple of float
        Per side, the median height (grey levels) of its samples' steps; NaN where the side's
        blur is (0.0: not measured).
    """

    sides: tuple[float, ...]
    normals: _F64
    offsets: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    errors: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    steps: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)

    @property
    def largest(self) -> float:
        """The largest side's blur (0.0 when no side was measured)."""
        finite = [s for s in self.sides if math.isfinite(s)]
        return max(finite) if finite else 0.0

    @property
    def width(self) -> float:
        """The blur's root-mean-square width over directions: ``√((a² + b²) / 2)`` of the larger
        blur of each pair of opposite sides, ``a`` and ``b`` (0.0 when a pair was not measured).
        A defocus of σ measures σ; a linear motion of ``L`` px measures ``L / √(4π)`` whatever
        its direction (its pairs measure ``L |n·m| / √(2π)``, and ``(n·m)²`` over two
        perpendicular normals sums to 1), where its largest side measures up to ``L / √(2π)``."""
        pairs = [max((s for s in self.sides[i::2] if math.isfinite(s)), default=math.nan) for i in (0, 1)]
        return math.sqrt((pairs[0] ** 2 + pairs[1] ** 2) / 2) if all(math.isfinite(p) for p in pairs) else 0.0

    @property
    def blurred(self) -> bool:
        """Whether these are a blurred tag's sides: the largest blur at least
        :data:`BLURRED_MIN_SIGMA`, every side measured, and opposite sides blurred alike
        (within :data:`BLURRED_PAIR_RATIO`, each side's blur allowed :data:`BLURRED_PAIR_ERRORS`
        standard errors towards the other's; a pair with a side whose step is under
        :data:`STEP_MIN_SHARE` of the candidate's is not compared)."""
        if self.largest < BLURRED_MIN_SIGMA or not all(math.isfinite(s) for s in self.sides):
            return False
        # sides sharper than a camera in focus blurs count as that sharp (a motion along a pair)
        floor = NOMINAL_BLURS_PX[1]
        least_step = STEP_MIN_SHARE * float(np.median(self.steps))
        for i in (0, 1):
            if min(self.steps[i], self.steps[i + 2]) < least_step:
                continue  # one side's step is a triangle's smeared into it: its slope measures that
            (low, e_low), (high, e_high) = sorted(
                ((max(self.sides[j], floor), self.errors[j]) for j in (i, i + 2)), key=lambda v: v[0]
            )
            spread = BLURRED_PAIR_ERRORS * np.nan_to_num(np.array([e_low, e_high]))
            if max(high - spread[1], low) > BLURRED_PAIR_RATIO * (low + spread[0]):
                return False
        return True

    def min_ranking(self, side: float, grid: int) -> float:
        """The coarse match a blurred candidate of this blur needs to be read by model: from
        :data:`BLURRED_MIN_RANKING` (the largest blur within a quarter of a cell of the ranking
        grid) down to :data:`BLURRED_MIN_RANKING_SMEARED` (half a cell or more), linearly in between.

        Parameters
        ----------
        side : float
            The data area's side (frame px).
        grid : int
            Cells per side of the ranking grid.

        Returns
        -------
        float
        """
        cells = self.largest * grid / max(side, 1.0)
        share = min(max(4.0 * cells - 1.0, 0.0), 1.0)  # 0 at a quarter of a cell, 1 at half a cell
        return BLURRED_MIN_RANKING + share * (BLURRED_MIN_RANKING_SMEARED - BLURRED_MIN_RANKING)

    def centred(self, quad: Quad) -> Quad:
        """``quad`` with each side moved onto its step's midpoint (:attr:`offsets`), the
        corners where the moved sides meet; ``quad`` itself when a side was not measured.

        A blurred step's midpoint is where the print's edge lies (a symmetric blur keeps it
        there), while a threshold's outline of a blurred data area lies where the threshold
        crosses the ramp: under a defocus of 2.5–3.5 px the local threshold's outlines missed
        the data area's corners by 1.7–2.3 px on average, the centred ones by 0.7–1.1 px, and an
        inverted tag's white data area, outlined 3 % of its side too wide, matched its printed
        tag coarsely by 0.60–0.65 (under :data:`BLURRED_MIN_RANKING`), centred by 0.72–0.85.
        """
        off = np.array(self.offsets)
        side = math.sqrt(max(quad.area, 1.0))
        if not np.isfinite(off).all() or np.abs(off).max() > _MAX_OFFSET * side:
            return quad
        normal, offset = lines_through(quad.corners)  # side i from corner i to i + 1
        # each side moved along its own normal by its offset along the measured outward one
        corners = polygon_vertices(normal, offset + off * (normal * self.normals).sum(axis=1), 4)
        if not np.isfinite(corners).all():
            return quad
        p, q = corners[2] - corners[0], corners[3] - corners[1]
        area = 0.5 * abs(float(p[0] * q[1] - p[1] * q[0]))
        return Quad(quad.polarity, corners, area, quad.inferred)


def edge_blur(gray: NDArray[np.uint8], quad: Quad) -> EdgeBlur:
    """The blur of a candidate's sides: per side, σ (frame px) of the Gaussian that blurs its step so.

    Each side is sampled across at nine places between 20 % and 80 % of its length (each the
    mean of parallel profiles along the side, :data:`_ALONG_SPREAD`); at each, the step's
    height (twice the distance of the outer third's median grey, the quiet zone, from the grey
    where the step is steepest, its midpoint) and its steepest slope give
    ``σ = height / (slope · √(2π))``; a side's blur is the median of its samples (motion blur
    widens the sides across the motion more than the others:
    :func:`~ottag_db.decode.camera_blur.measured_blurs` reads it from them).

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    quad : Quad
        The candidate (frame pixels).

    Returns
    -------
    EdgeBlur
        Per side σ in frame px (NaN where no step showed).
    """
    side = math.sqrt(max(quad.area, 1.0))
    reach = min(_ACROSS_MAX, max(4.0, 0.2 * side))
    across = np.arange(-reach, reach + 1e-9, _ACROSS_STEP)
    # each side's profiles (compiled, ottag_native.blur): across it along its outward normal, at
    # the places _ALONG of its length, each place as len(_ALONG_SPREAD) parallel lines
    rows = 4 * len(_ALONG) * len(_ALONG_SPREAD)
    xs, ys = np.empty((rows, len(across)), np.float32), np.empty((rows, len(across)), np.float32)
    normal, length = np.empty((4, 2)), np.empty(4)
    corners = np.ascontiguousarray(quad.corners, dtype=np.float64)
    side_samples(corners, across, _ALONG, _ALONG_SPREAD, xs, ys, normal, length)
    profiles = cv2.remap(gray, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    profile = profiles.reshape(4 * len(_ALONG), len(_ALONG_SPREAD), len(across)).mean(axis=1)
    spread = _SMOOTHING_PX / _ACROSS_STEP  # along each profile only (a row is one sample)
    smooth = cv2.GaussianBlur(profile, (2 * math.ceil(3 * spread) + 1, 1), spread, borderType=cv2.BORDER_REPLICATE)
    # per sample (compiled, ottag_native.blur): the step's height from the quiet zone's side
    # only — twice the outer third's median grey's distance from the grey at the steepest point,
    # a blurred step's midpoint (inside, the triangles can come within a few pixels of the data
    # area's border) — and its slope there give σ, the smoothing's own blur taken out; a sample
    # whose step is under the least height (_MIN_HEIGHT) does not count. Per side, with at least
    # half of its samples: their median σ, its standard error from their interquartile range (as
    # the median absolute deviation for a normal scatter; but also wide where a motion smears a
    # triangle near the side across half of it: 5 samples measured 9 px, 4 measured 3 px, as the
    # opposite side), the step's midpoint (the steepest point's median position) and its height.
    out = np.empty((4, 4))
    side_blurs(
        profile, smooth, across, length, out, _ACROSS_STEP, _SMOOTHING_PX, STEP_MIN_SHARE, _NOISE_HEIGHT, _MIN_HEIGHT
    )
    sides, offsets, errors, steps = (tuple(float(v) for v in row) for row in out)
    return EdgeBlur(sides, normal, offsets, errors, steps)
