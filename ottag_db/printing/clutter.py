"""Synthetic camera frames without tags: other markers, checkerboards, text and noise.

The negatives of the decoder tests and the clutter benchmark (``benchmarks/decode_clutter.py``):
what a decoder must refuse, and what refusing it costs. Frames are drawn with
:func:`~ottag_db.printing.scenes.render_scene` (same camera, degradations and conventions).
"""

from __future__ import annotations

from collections.abc import Iterator

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.printing.scenes import camera_matrix, pose_homography, random_pose, render_scene

__all__ = ["blank_frames", "clutter_frames", "noise_frames", "oblique_marker_frames"]

#: ArUco dictionaries of the marker patches: 6×6, AprilTag 36h11, 4×4.
_DICTIONARIES = (cv2.aruco.DICT_6X6_250, cv2.aruco.DICT_APRILTAG_36h11, cv2.aruco.DICT_4X4_50)


def _patch(kind: int, rng: np.random.Generator) -> NDArray[np.uint8]:
    """A flat patch: kind 0–2 a marker of :data:`_DICTIONARIES` (240 px, 60 px white border),
    3 a checkerboard of 4–8 squares (240 px, 30 px border), 4 white text on a black panel."""
    if kind < 3:
        d = cv2.aruco.getPredefinedDictionary(_DICTIONARIES[kind])
        img = cv2.aruco.generateImageMarker(d, int(rng.integers(30)), 240)
        return np.asarray(cv2.copyMakeBorder(img, 60, 60, 60, 60, cv2.BORDER_CONSTANT, value=255), np.uint8)
    if kind == 3:
        sq = int(rng.integers(4, 9))
        img = ((np.indices((sq, sq)).sum(axis=0) % 2) * 255).astype(np.uint8)
        img = cv2.resize(img, (240, 240), interpolation=cv2.INTER_NEAREST)
        return np.asarray(cv2.copyMakeBorder(img, 30, 30, 30, 30, cv2.BORDER_CONSTANT, value=255), np.uint8)
    text: NDArray[np.uint8] = np.full((200, 300), 255, np.uint8)
    cv2.rectangle(text, (20, 20), (280, 180), 0, -1)
    for row in range(3):
        cv2.putText(text, "AVW7>4", (30, 70 + 45 * row), cv2.FONT_HERSHEY_SIMPLEX, 1.4, 255, 3)
    return text


def clutter_frames(rng: np.random.Generator, n: int) -> Iterator[NDArray[np.uint8]]:
    """640×480 frames, each with three flat patches side by side: markers (ArUco 6×6, AprilTag
    36h11, ArUco 4×4), checkerboards and white text, cycling through the five kinds.

    Each patch is 80–160 px wide (frontal equivalent), tilted 0–50° about a random axis; the
    frame gets a blur of σ 0–1 px, noise of σ 0–5 grey levels, a light gradient of 0–0.5 and
    JPEG 70.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of every random choice.
    n : int
        Frames.

    Yields
    ------
    numpy.ndarray
        ``(480, 640)`` uint8 frames.
    """
    k_mat = camera_matrix()
    for i in range(n):
        patches = []
        for j in range(3):
            img = _patch((i + j) % 5, rng)
            width = rng.uniform(80, 160)
            r_mat, t = random_pose(rng, k_mat, 0.1, width, rng.uniform(0, 50), (110 + 210 * j, 240))
            patches.append((img, pose_homography(k_mat, r_mat, t, 0.1)))
        blur, noise, gradient = rng.uniform(0, 1), rng.uniform(0, 5), rng.uniform(0, 0.5)
        yield render_scene((480, 640), [], rng, blur=blur, noise=noise, gradient=gradient, jpeg=70, extra=patches).image


def noise_frames(rng: np.random.Generator, n: int) -> Iterator[NDArray[np.uint8]]:
    """``2 n`` 640×480 frames of noise: uniform grey levels, then the same blurred (σ 3 px), in turn.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the noise.
    n : int
        Pairs of frames.

    Yields
    ------
    numpy.ndarray
        ``(480, 640)`` uint8 frames.
    """
    for _ in range(n):
        yield rng.integers(0, 256, (480, 640), dtype=np.uint8)
        yield np.asarray(cv2.GaussianBlur(rng.integers(0, 256, (480, 640), dtype=np.uint8), (0, 0), 3), np.uint8)


def blank_frames(rng: np.random.Generator, n: int) -> Iterator[NDArray[np.uint8]]:
    """640×480 frames of nothing but a flat grey (level 15–240) and sensor noise (σ 1–4): a
    blank wall, a lens cap, a dark room.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the levels and the noise.
    n : int
        Frames.

    Yields
    ------
    numpy.ndarray
        ``(480, 640)`` uint8 frames.
    """
    for _ in range(n):
        level, sigma = rng.uniform(15, 240), rng.uniform(1, 4)
        yield np.clip(np.rint(level + rng.normal(0, sigma, (480, 640))), 0, 255).astype(np.uint8)


def oblique_marker_frames(
    rng: np.random.Generator, n: int, tilt_deg: tuple[float, float] = (76.0, 88.0)
) -> Iterator[NDArray[np.uint8]]:
    """640×480 frames of one ArUco 6×6 marker (a random id, white border of a quarter of its side)
    seen nearly edge-on: 90–200 px wide (frontal equivalent), tilt in ``tilt_deg``; blur σ 0–1 px,
    noise σ 0–4, gradient 0–0.4, JPEG 80.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of every random choice.
    n : int
        Frames.
    tilt_deg : (float, float)
        Tilt range, degrees.

    Yields
    ------
    numpy.ndarray
        ``(480, 640)`` uint8 frames.
    """
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    k_mat = camera_matrix()
    border = np.array([[1.5, 0, -0.25], [0, 1.5, -0.25], [0, 0, 1.0]])  # marker → patch with its border
    for _ in range(n):
        marker = cv2.aruco.generateImageMarker(dictionary, int(rng.integers(250)), 400)
        patch = np.asarray(cv2.copyMakeBorder(marker, 100, 100, 100, 100, cv2.BORDER_CONSTANT, value=255), np.uint8)
        r_mat, t = random_pose(rng, k_mat, 0.1, rng.uniform(90, 200), rng.uniform(*tilt_deg), (320, 240))
        hom = pose_homography(k_mat, r_mat, t, 0.1) @ border
        blur, noise, gradient = rng.uniform(0, 1), rng.uniform(0, 4), rng.uniform(0, 0.4)
        yield render_scene(
            (480, 640), [], rng, extra=[(patch, hom)], blur=blur, noise=noise, gradient=gradient, jpeg=80
        ).image
