"""The planar pose ambiguity: both mirrored poses of a tag and the likelihood of the mirrored
pose relative to the chosen one.

A nearly fronto-parallel tag fits two poses tilted opposite ways about the line of sight almost
equally; on a data area 28–70 px wide their images differ by about a tenth of a pixel. Here:

- :func:`weighted_lm`: Levenberg–Marquardt on weighted, Cauchy-reweighted reprojection errors
  (each correspondence's weight; corners first, then the points);
- :func:`mirrored_minima`: the refined pose of lowest cost and its mirror (the other minimum,
  or the mirror as it lies when there is only one);
- :func:`likelihood_ratio`: the mirror's likelihood relative to the pose, the noise scale
  estimated from the pose's residuals.

Used by :func:`ottag_db.decode.pose.estimate_pose`; arrays are ``obj`` (n, 3) tag-plane points
and ``img`` (n, 2) image points, the 4 corners first.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "AMBIGUITY_LIMIT",
    "AMBIGUITY_MIN_ANGLE_DEG",
    "MIN_NOISE_PX",
    "Minimum",
    "ippe",
    "likelihood_ratio",
    "mirrored_minima",
    "normal_angle_deg",
    "weighted_cost",
    "weighted_lm",
]

_F64 = NDArray[np.float64]
#: A refined pose: ``rvec``, ``tvec`` and its weighted cost.
Minimum = tuple[_F64, _F64, float]

#: Smallest noise (px per axis) assumed for a corner when the ambiguity is judged. The noise is
#: estimated from each pose's own residuals (their median, robust to a stray vertex), which a
#: fit of 6 unknowns to 12 points makes small by chance now and then; 0.03 px is about the
#: median of that estimate on data areas 28–70 px wide (benchmarks/pose_flips.py renders, 1 %
#: below 0.007 px), so chance cannot make a pose look surer than a typical image allows.
MIN_NOISE_PX = 0.03
#: :attr:`~ottag_db.decode.pose.Pose.ambiguous` when the mirrored pose is at least this likely
#: relative to the pose (likelihood ratio): the pose stands alone only when the evidence for it
#: over its mirror is strong on Jeffreys' scale (a ratio of 10 or more); a user who needs more
#: (or less) certainty reads :attr:`~ottag_db.decode.pose.Pose.ambiguity` directly.
AMBIGUITY_LIMIT = 0.1
#: … and only when the two poses' tag normals differ by more than this (degrees). Nearly
#: head-on, the mirrored pose is tilted the other way by about as much as the pose, and both
#: tilts lie within the normal's own uncertainty at the small sizes where the ambiguity arises
#: (several degrees on data areas 28–40 px wide): such a pair is not a choice between two
#: readings of the scene.
AMBIGUITY_MIN_ANGLE_DEG = 10.0
#: Two refined poses whose tag normals are closer than this (degrees) are one minimum.
_SAME_MINIMUM_DEG = 0.5
_LM_ITERATIONS = 30


def _cauchy_weights(res: _F64, weights: _F64, robust_px: float | None) -> _F64:
    """Each correspondence's weight, Cauchy-reweighted by its residual ``res`` (n, 2) at ``robust_px``."""
    return weights if robust_px is None else weights / (1.0 + np.sum(res**2, axis=1) / robust_px**2)


def weighted_cost(
    obj: _F64, img: _F64, rvec: _F64, tvec: _F64, k: _F64, dist: _F64 | None, weights: _F64, robust_px: float | None
) -> float:
    """The cost :func:`weighted_lm` minimises, at one pose.

    Parameters
    ----------
    obj, img : ndarray
        Tag-plane points (n, 3) and their image points (n, 2).
    rvec, tvec : ndarray
        The pose (Rodrigues vector, translation).
    k, dist : ndarray or None
        Intrinsic matrix and distortion coefficients (None: none).
    weights : ndarray
        Weight of each correspondence (0 leaves it out).
    robust_px : float or None
        Cauchy scale, px (None: no reweighting).

    Returns
    -------
    float
        Sum of weight × reweighting × squared error (px²).
    """
    proj, _ = cv2.projectPoints(obj, rvec, tvec, k, dist)
    res = proj.reshape(-1, 2) - img
    return float(np.sum(_cauchy_weights(res, weights, robust_px) * np.sum(res**2, axis=1)))


def weighted_lm(
    obj: _F64, img: _F64, k: _F64, dist: _F64 | None, rvec: _F64, tvec: _F64, weights: _F64, robust_px: float | None
) -> Minimum:
    """Levenberg–Marquardt on the weighted (and, with ``robust_px``, Cauchy-reweighted) squared
    reprojection error, from the pose ``rvec``, ``tvec``.

    Parameters
    ----------
    obj, img, k, dist, weights, robust_px
        As for :func:`weighted_cost`.
    rvec, tvec : ndarray
        The starting pose.

    Returns
    -------
    Minimum
        The refined ``rvec``, ``tvec`` and the final weighted cost.
    """
    rv, tv = rvec.astype(np.float64).reshape(3).copy(), tvec.astype(np.float64).reshape(3).copy()

    def residuals(r: _F64, t: _F64) -> tuple[_F64, _F64]:
        proj, jac = cv2.projectPoints(obj, r, t, k, dist)
        return proj.reshape(-1, 2) - img, np.asarray(jac, dtype=np.float64)[:, :6]

    def cost(res: _F64, w: _F64) -> float:
        return float(np.sum(w * np.sum(res**2, axis=1)))

    lam = 1e-3
    res, jac = residuals(rv, tv)
    for _ in range(_LM_ITERATIONS):
        w = _cauchy_weights(res, weights, robust_px)
        w2 = np.repeat(w, 2)
        a = jac.T @ (w2[:, None] * jac)
        g = jac.T @ (w2 * res.ravel())
        c0 = cost(res, w)
        improved = False
        for _ in range(12):
            step = -np.linalg.solve(a + lam * np.diag(np.diag(a) + 1e-12), g)
            r1, t1 = rv + step[:3], tv + step[3:]
            res1, jac1 = residuals(r1, t1)
            if cost(res1, w) < c0:
                rv, tv, res, jac = r1, t1, res1, jac1
                lam = max(lam / 10, 1e-9)
                improved = True
                break
            lam *= 10
        # converged: the step moves the rotation by < 1e-9 rad and the position by < 1e-9 of the distance
        if not improved or (
            float(np.max(np.abs(step[:3]))) < 1e-9
            and float(np.linalg.norm(step[3:])) < 1e-9 * float(np.linalg.norm(tv))
        ):
            break
    return rv, tv, cost(res, _cauchy_weights(res, weights, robust_px))


def ippe(obj: _F64, img: _F64, k: _F64, dist: _F64 | None) -> list[tuple[_F64, _F64]]:
    """The IPPE solutions of planar correspondences (``cv2.SOLVEPNP_IPPE``, at least 4 points).

    Parameters
    ----------
    obj, img, k, dist
        As for :func:`weighted_cost`.

    Returns
    -------
    list of (rvec, tvec)
        Zero to two poses.
    """
    count, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, k, dist, flags=cv2.SOLVEPNP_IPPE)
    return [
        (np.asarray(rvecs[i], dtype=np.float64).reshape(3), np.asarray(tvecs[i], dtype=np.float64).reshape(3))
        for i in range(int(count))
    ]


def normal_angle_deg(rv1: _F64, rv2: _F64) -> float:
    """Angle between the tag normals (third columns of R) of two poses.

    Parameters
    ----------
    rv1, rv2 : ndarray, shape (3,)
        Rodrigues vectors.

    Returns
    -------
    float
        Degrees.
    """
    n1 = np.asarray(cv2.Rodrigues(rv1)[0], dtype=np.float64)[:, 2]
    n2 = np.asarray(cv2.Rodrigues(rv2)[0], dtype=np.float64)[:, 2]
    return math.degrees(math.acos(float(np.clip(n1 @ n2, -1.0, 1.0))))


def _mirror(obj: _F64, rvec: _F64, tvec: _F64, k: _F64, dist: _F64 | None) -> tuple[_F64, _F64]:
    """The pose's mirror: the IPPE solution of its own noise-free image farther from it."""
    proj, _ = cv2.projectPoints(obj, rvec, tvec, k, dist)
    img = np.asarray(proj, dtype=np.float64).reshape(-1, 2)
    return max(ippe(obj, img, k, dist), key=lambda c: normal_angle_deg(c[0], rvec))


def mirrored_minima(
    obj: _F64, img: _F64, k: _F64, dist: _F64 | None, weights: _F64, robust_px: float | None
) -> tuple[Minimum, Minimum]:
    """The pose of lowest weighted cost and its mirror of the planar ambiguity.

    Both IPPE solutions of the correspondences with a weight are refined by :func:`weighted_lm`;
    when both end in one minimum, the mirror of that minimum is refined too, and when that also
    returns to it, the mirror is kept as it lies (there is no second minimum).

    Parameters
    ----------
    obj, img, k, dist, weights, robust_px
        As for :func:`weighted_cost` (at least 4 correspondences with a weight).

    Returns
    -------
    best, mirror : Minimum
        The pose of lowest cost and the other.
    """
    used = weights > 0
    starts = ippe(np.ascontiguousarray(obj[used]), np.ascontiguousarray(img[used]), k, dist)
    minima = sorted((weighted_lm(obj, img, k, dist, rv, tv, weights, robust_px) for rv, tv in starts), key=_cost)
    best, alt = minima[0], minima[-1]
    if normal_angle_deg(best[0], alt[0]) < _SAME_MINIMUM_DEG:
        alt = weighted_lm(obj, img, k, dist, *_mirror(obj, best[0], best[1], k, dist), weights, robust_px)
        best, alt = sorted((best, alt), key=_cost)
        if normal_angle_deg(best[0], alt[0]) < _SAME_MINIMUM_DEG:
            mr, mt = _mirror(obj, best[0], best[1], k, dist)
            alt = (mr, mt, weighted_cost(obj, img, mr, mt, k, dist, weights, robust_px))
    return best, alt


def _cost(m: Minimum) -> float:
    return m[2]


def _noise_var(obj: _F64, img: _F64, k: _F64, dist: _F64 | None, weights: _F64, pose: Minimum) -> float:
    """A corner's noise variance (px²) from the pose's residuals: their median, a vertex's squared
    error counting ``1 / corner weight``, scaled to a 2-D Gaussian's (median of χ²₂ = ln 4) and to
    the degrees of freedom left by the 6 unknowns; at least ``MIN_NOISE_PX²``."""
    used = weights > 0
    proj, _ = cv2.projectPoints(obj, pose[0], pose[1], k, dist)
    r2 = (weights * np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1) / float(weights.max()))[used]
    n = int(used.sum())
    return max(MIN_NOISE_PX**2, float(np.median(r2)) / math.log(4.0) * 2 * n / max(2 * n - 6, 1))


def likelihood_ratio(
    obj: _F64, img: _F64, k: _F64, dist: _F64 | None, weights: _F64, best: Minimum, mirror: Minimum
) -> float:
    """Likelihood of ``mirror`` relative to ``best`` under the noise model, in [0, 1].

    Each correspondence's error is Gaussian with variance ``σ² · corner_weight / weight`` (a
    corner's σ², a vertex's ``corner_weight`` times it; ``corner_weight = weights.max()``), with
    the Cauchy tails of the costs; σ² is estimated from the pose's residuals (robustly, their
    median; at least :data:`MIN_NOISE_PX` squared). The ratio is
    ``exp(-(cost(mirror) - cost(best)) / (2 σ² corner_weight))``.

    Parameters
    ----------
    obj, img, k, dist, weights
        As for :func:`weighted_cost`.
    best, mirror : Minimum
        From :func:`mirrored_minima` (same weights).

    Returns
    -------
    float
        1: the two fit alike; near 0: the image tells them apart.
    """
    var = _noise_var(obj, img, k, dist, weights, best)
    return math.exp(-max(mirror[2] - best[2], 0.0) / (2.0 * float(weights.max()) * var))
