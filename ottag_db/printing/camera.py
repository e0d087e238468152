"""Pinhole camera of the synthetic scenes: intrinsics, tag poses, homographies.

Conventions: image coordinates are pixels with the origin at the centre of the top-left pixel,
x right, y down; camera frame as OpenCV's (x right, y down, z forward). The tag frame has x
right and y down along the printed data area and z = x × y pointing into it, so a frontal view
has R = I; its origin is the data area's top-left corner.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["camera_matrix", "pose_homography", "project", "random_pose"]

F64 = NDArray[np.float64]


def camera_matrix(f: float = 700.0, w: int = 640, h: int = 480) -> F64:
    """Pinhole intrinsics with square pixels and the principal point at the image centre.

    Parameters
    ----------
    f : float
        Focal length, px.
    w, h : int
        Image width and height, px.

    Returns
    -------
    ndarray, shape (3, 3)
        ``K`` with ``cx = (w − 1) / 2``, ``cy = (h − 1) / 2`` (pixel-centre origin).
    """
    return np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])


def pose_homography(k_mat: F64, r_mat: F64, t: F64, size: float) -> F64:
    """Homography from data-area units to the image for a tag at pose (R, t).

    Parameters
    ----------
    k_mat : ndarray, shape (3, 3)
        Camera intrinsics.
    r_mat : ndarray, shape (3, 3)
        Rotation tag frame → camera frame.
    t : ndarray, shape (3,)
        Position of the data area's top-left corner in the camera frame, in the unit of ``size``.
    size : float
        Side of the data area.

    Returns
    -------
    ndarray, shape (3, 3)
        The homography, normalised to ``H[2, 2] = 1``.
    """
    h = k_mat @ np.c_[r_mat[:, 0] * size, r_mat[:, 1] * size, t]
    out: F64 = h / h[2, 2]
    return out


def _rotation(axis: F64, angle: float) -> F64:
    r, _ = cv2.Rodrigues(np.asarray(axis, dtype=np.float64).reshape(3, 1) * angle)
    out: F64 = np.asarray(r, dtype=np.float64)
    return out


def random_pose(
    rng: np.random.Generator,
    k_mat: F64,
    size: float,
    width_px: float,
    tilt_deg: float,
    center_px: tuple[float, float],
) -> tuple[F64, F64]:
    """A pose of a tag seen ``width_px`` wide (frontal-equivalent), tilted, at a random angle.

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws the in-plane rotation and the tilt axis (two uniform angles).
    k_mat : ndarray, shape (3, 3)
        Camera intrinsics.
    size : float
        Side of the data area (the unit of the returned ``t``).
    width_px : float
        Side of the data area in pixels if it were seen frontally at the same distance.
    tilt_deg : float
        Angle between the tag's normal and the optical axis, degrees. The tag always turns its
        printed face to the camera: where the drawn tilt axis would show its back (the ray to
        ``center_px`` more than ``90 - tilt_deg`` degrees off the axis, on the far side), the
        tilt goes the other way about that axis.
    center_px : (float, float)
        Image position of the data area's centre, px.

    Returns
    -------
    r_mat : ndarray, shape (3, 3)
        Rotation tag frame → camera frame.
    t : ndarray, shape (3,)
        Position of the data area's top-left corner in the camera frame.
    """
    f = float(k_mat[0, 0])
    z = f * size / width_px
    phi = rng.uniform(0, 2 * math.pi)
    psi = rng.uniform(0, 2 * math.pi)
    tilt_axis = np.array([math.cos(phi), math.sin(phi), 0.0])
    spin = _rotation(np.array([0, 0, 1.0]), psi)
    r = _rotation(tilt_axis, math.radians(tilt_deg)) @ spin
    c = z * np.linalg.solve(k_mat, np.array([center_px[0], center_px[1], 1.0]))
    if r[:, 2] @ c <= 0:
        # The camera would be behind the tag's plane (a tilt near 90° at a centre off the
        # optical axis): the frame would show the back of the paper, the tag mirrored. Tilted
        # the other way about the same axis the printed face is toward the camera.
        r = _rotation(-tilt_axis, math.radians(tilt_deg)) @ spin
    t = c - r @ np.array([size / 2, size / 2, 0.0])
    return r, t


def project(homography: F64, points: ArrayLike) -> F64:
    """Apply a homography to points.

    Parameters
    ----------
    homography : ndarray, shape (3, 3)
        The map.
    points : array_like, shape (n, 2)
        Points to map.

    Returns
    -------
    ndarray, shape (n, 2)
        Mapped points (dehomogenised).
    """
    pts = np.asarray(points, dtype=np.float64)
    ph = np.c_[pts, np.ones(len(pts))] @ homography.T
    out: F64 = ph[:, :2] / ph[:, 2:3]
    return out
