"""The camera blurs a tag is drawn with when it is read by model.

A blurred candidate (:attr:`~ottag_db.decode.blur.EdgeBlur.blurred`) is judged as a camera with
its blur would see each printed tag (:func:`~ottag_db.decode.model_align.judge`): a defocus (a
Gaussian) or a linear motion on top of the optics' own blur (:class:`Blur`, drawn with
:func:`motion_kernel`). Its sides' blurs give the blurs to try (:func:`measured_blurs`), and the
one that fits the best aligned tag's view is refined by a pattern search (:func:`refined_blur`).
The camera's sensor noise (:func:`sensor_noise`) tells how closely a tag so drawn can fit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.blur import NOMINAL_BLURS_PX, EdgeBlur

__all__ = ["Blur", "FrameCamera", "measured_blurs", "motion_kernel", "refined_blur", "sensor_noise"]

#: The motion lengths drawn, as fractions of the length the sides measure: a side's width
#: mixes the motion with the optics' blur, which a box of the measured variance only
#: approximates (the outline then chooses).
_MOTION_LENGTHS = (0.7, 0.85, 1.0, 1.15, 1.3)
#: The motion directions drawn about each one the sides give (degrees): the sides' widths
#: place it within about 10°.
_MOTION_TURNS = (-10.0, 0.0, 10.0)
#: The pattern search of :func:`refined_blur`: its first steps (the factor on σ and on the
#: motion's length, the turn of its direction in degrees), each halved when no move along it
#: fits better, down to the last ones; at most :data:`_REFINE_EVALUATIONS` blurs drawn per start.
_REFINE_STEPS = (1.2, 1.2, 8.0)
_REFINE_LAST = (1.03, 1.03, 1.0)
_REFINE_EVALUATIONS = 16
#: The turns (degrees) of a measured motion's direction tried before the pattern search: the
#: sides placed a 15–17 px motion up to 30° off, beyond the search's reach from one start.
_SWEEP = tuple(float(a) for a in range(0, 180, 30))
#: The directions are also swept at this multiple of the longest measured motion: a triangle
#: smeared across a side lowers its step's height, and the side then measures a long motion
#: short (17 px motions measured 8–12 px on tags with a triangle along the sides across the
#: motion), from where the pattern search's steps of :data:`_REFINE_STEPS` do not reach it.
_LONGER = 1.6


@dataclass(frozen=True)
class Blur:
    """A camera blur to draw a tag with: a Gaussian of ``sigma`` px, then (``length`` > 1) a
    linear motion of ``length`` px along ``angle_deg`` (screen coordinates, from the x axis)."""

    sigma: float
    length: float = 0.0
    angle_deg: float = 0.0

    def apply(self, image: NDArray[np.float32]) -> NDArray[np.float32]:
        """``image`` blurred so (float32, same shape).

        Parameters
        ----------
        image : numpy.ndarray
            ``(H, W)`` float32.

        Returns
        -------
        numpy.ndarray
        """
        out = cv2.GaussianBlur(image, (0, 0), self.sigma)
        if self.length > 1.0:
            out = cv2.filter2D(out, -1, motion_kernel(self.length, self.angle_deg), borderType=cv2.BORDER_REPLICATE)
        return np.asarray(out, dtype=np.float32)


@dataclass(frozen=True)
class FrameCamera:
    """The camera a blurred candidate was seen with, to judge every tag alike
    (:func:`~ottag_db.decode.model_align.judge`): its blur
    (:func:`~ottag_db.decode.model_align.fit_blur`) and the σ (grey levels) of the sensor noise
    around the candidate (:func:`sensor_noise`), measured once per candidate."""

    blur: Blur
    noise: float


def motion_kernel(length: float, angle_deg: float) -> NDArray[np.float32]:
    """A normalized kernel of a linear motion ``length`` px long along ``angle_deg``.

    Parameters
    ----------
    length : float
        px (> 1).
    angle_deg : float
        Direction of the motion, degrees from the x axis (screen coordinates).

    Returns
    -------
    numpy.ndarray
        Odd square float32 kernel summing to 1.
    """
    size = math.ceil(length) | 1
    c = (size - 1) / 2
    half = length / 2
    dx, dy = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    t = np.linspace(-half, half, 4 * size + 1)  # the segment, area-sampled (bilinear weights)
    x, y = c + t * dx, c + t * dy
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    xs = np.concatenate([x0, x0 + 1, x0, x0 + 1]).astype(np.intp)
    ys = np.concatenate([y0, y0, y0 + 1, y0 + 1]).astype(np.intp)
    weights = np.concatenate([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
    inside = (xs >= 0) & (xs < size) & (ys >= 0) & (ys < size)
    cells = np.bincount(ys[inside] * size + xs[inside], weights[inside], minlength=size * size)
    kernel32 = cells.reshape(size, size).astype(np.float32)
    total = float(kernel32.sum())
    return kernel32 / total if total > 0 else kernel32


def sensor_noise(image: NDArray[np.float32]) -> float:
    """The standard deviation (grey levels) of the sensor noise in ``image``.

    Immerkær's estimate, made robust: the image filtered by the difference of two Laplacians
    (``[1 -2 1; -2 4 -2; 1 -2 1]``), which cancels any plane and nearly cancels a blurred
    step, leaves white noise of σ multiplied by 6; its median absolute value is then 0.6745 of
    that. The median keeps the sharp steps of a tag's triangles and sides out (they fill a few
    pixels in ten of a data area's neighbourhood). It is taken over every other row and column
    (neighbouring responses share most of their pixels; the median's sort is the cost).

    Parameters
    ----------
    image : numpy.ndarray
        ``(H, W)`` float32, at least 3 × 3.

    Returns
    -------
    float
    """
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float32)
    response = cv2.filter2D(image, cv2.CV_32F, kernel)[1:-1:2, 1:-1:2]
    return float(np.median(np.abs(response))) / (6.0 * 0.6745)


def measured_blurs(blur: EdgeBlur | None) -> tuple[Blur, ...]:
    """The blurs a blurred candidate's sides allow, to draw a tag with when it is judged.

    For a candidate whose sides measure more than the nominal blurs (:data:`~ottag_db.decode.blur.NOMINAL_BLURS_PX`;
    ``blur.largest`` above the largest) a defocus — a Gaussian of the largest
    side's σ, a quarter less and more — and a linear motion: a motion of ``L`` px along ``m``
    smears a side of normal ``n`` over ``L |n·m|`` px, which the steepest slope of
    :func:`~ottag_db.decode.blur.edge_blur` measures as ``σ = L |n·m| / √(2π)`` (σ² = σ₀² + L² (n·m)² / 2π, the optics'
    blur σ₀ added), so the two pairs of opposite sides give ``L`` and ``m`` up to the mirror
    image about a side's normal (both are drawn, each in lengths and directions about the
    measured ones). Reading by model takes the one that fits the best aligned tag's whole view
    (:func:`~ottag_db.decode.model_align.fit_blur`) and judges every tag with it.

    Parameters
    ----------
    blur : EdgeBlur or None
        The candidate's measured blur (None: not measured).

    Returns
    -------
    tuple of Blur
        Empty when the sides measure no more than the nominal blurs.
    """
    if blur is None or blur.largest <= NOMINAL_BLURS_PX[-1]:
        return ()
    sigma = blur.largest
    out = [Blur(0.75 * sigma), Blur(sigma), Blur(1.25 * sigma)]
    pairs = []
    for i in (0, 1):  # opposite sides i, i + 2
        values = [blur.sides[j] for j in (i, i + 2) if math.isfinite(blur.sides[j])]
        if not values:
            return tuple(out)
        n = blur.normals[i] - blur.normals[i + 2]  # (outward normals of opposite sides: opposed)
        pairs.append((math.atan2(n[1], n[0]), float(np.median(values))))
    base = NOMINAL_BLURS_PX[1]
    theta = np.radians(np.arange(0.0, 180.0, 1.0))
    spread = np.array([max(s * s - base * base, 0.0) * 2 * math.pi for _, s in pairs])  # L² (n·m)²
    cos2 = np.stack([np.cos(theta - a) ** 2 for a, _ in pairs])  # (2, angles)
    # L² per direction by least squares over both pairs, then the direction that fits best
    l2 = (cos2 * spread[:, None]).sum(axis=0) / np.maximum((cos2 * cos2).sum(axis=0), 1e-9)
    resid = ((cos2 * l2[None, :] - spread[:, None]) ** 2).sum(axis=0)
    best = int(np.argmin(resid))
    length = math.sqrt(max(float(l2[best]), 0.0))
    if length > 2.0:
        angle = math.degrees(float(theta[best]))
        mirror = (math.degrees(2 * pairs[0][0]) - angle) % 180.0  # reflected about the first normal
        angles = [(a + turn) % 180.0 for a in dict.fromkeys((angle, mirror)) for turn in _MOTION_TURNS]
        out += [Blur(base, f * length, a) for a in angles for f in _MOTION_LENGTHS]
    return tuple(out)


def refined_blur(misfit: Callable[[Blur], float], blurs: tuple[Blur, ...]) -> Blur | None:
    """The blur that fits a candidate's view best: the best defocus and the best motion of
    ``blurs``, each refined by a pattern search on ``misfit``, and the better of the two.

    The sides measure a motion only roughly: a side's steepest slope is lowered by triangles
    within the blur's reach of it, and its plateau is cut short by a long smear, so a motion of
    15–17 px measured 10–14 px and up to 30° off, and the nearest measured motion (or a
    defocus) then misfits the tag seen by 0.13–0.26 of its contrast, where the true one leaves
    0.04–0.07 (:data:`~ottag_db.decode.blur.BLURRED_MAX_MISFIT`). The motion starts from the best measured direction
    at the measured length, swept over a half turn (:data:`_SWEEP`; a motion along the data
    area's diagonal widens all four sides alike, as a defocus does: such sides get a motion
    too); the search then moves σ, the length and the direction by :data:`_REFINE_STEPS`,
    halving each step that finds nothing better, within :data:`_REFINE_EVALUATIONS` drawings.

    Parameters
    ----------
    misfit : callable
        A blur → how badly the tag drawn with it fits the view (smaller: better).
    blurs : tuple of Blur
        The measured blurs (:func:`measured_blurs`).

    Returns
    -------
    Blur or None
        None when ``blurs`` is empty.
    """
    if not blurs:
        return None
    cache: dict[Blur, float] = {}

    def cost(blur: Blur) -> float:
        if blur not in cache:
            cache[blur] = misfit(blur)
        return cache[blur]

    defocus = [b for b in blurs if b.length <= 1.0]
    motions = [b for b in blurs if b.length > 1.0]
    if not motions and defocus:
        # sides blurred alike: a defocus, or a motion along the data area's diagonal, which
        # widens every side by as much (of a length the median σ gives, in any direction)
        sigma = float(np.median([b.sigma for b in defocus]))
        length = math.sqrt(2 * math.pi * max(sigma * sigma - NOMINAL_BLURS_PX[1] ** 2, 0.0))
        motions = [Blur(NOMINAL_BLURS_PX[1], length, 0.0)] if length > 2.0 else []
    starts = [min(defocus, key=cost)] if defocus else []
    if motions:
        # the measured directions at the measured length, then the best of them swept over a
        # half turn (the pattern search then refines length and direction together)
        middle = float(np.median([b.length for b in motions]))
        first = min((b for b in motions if b.length == middle), key=cost, default=motions[0])
        # swept at the shortest and the longest measured length too, and beyond it (_LONGER):
        # at a length far off the tag seen, the best turn can lie 60° off (a 17 px motion
        # measured 27 px: best at 86°, not the motion's 149°), and the pattern search cannot
        # climb back from there
        longest = max(b.length for b in motions)
        lengths = dict.fromkeys((first.length, min(b.length for b in motions), longest, _LONGER * longest))
        swept = (replace(first, length=n, angle_deg=(first.angle_deg + a) % 180.0) for n in lengths for a in _SWEEP)
        starts.append(min(swept, key=cost))
    out = []
    for start in starts:
        best, steps, spent = start, list(_REFINE_STEPS), 0
        motion = start.length > 1.0
        while spent < _REFINE_EVALUATIONS and any(steps[i] > _REFINE_LAST[i] for i in (0, 1, 2) if motion or i == 0):
            for i in (0, 1, 2) if motion else (0,):
                if steps[i] <= _REFINE_LAST[i]:
                    continue
                for sign in (1.0, -1.0):
                    if i == 0:
                        trial = replace(best, sigma=best.sigma * steps[0] ** sign)
                    elif i == 1:
                        trial = replace(best, length=best.length * steps[1] ** sign)
                    else:
                        trial = replace(best, angle_deg=(best.angle_deg + sign * steps[2]) % 180.0)
                    spent += trial not in cache
                    if cost(trial) < cost(best):
                        best = trial
                        break
                else:
                    steps[i] = 1.0 + (steps[i] - 1.0) / 2 if i < 2 else steps[i] / 2
        out.append(best)
    return min(out, key=cost)
