"""Image stage: any image array → 8-bit grey, and the Otsu split of a grey-level histogram."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from ottag_native.histogram import otsu_split

from ottag_db.errors import DecodeError

__all__ = [
    "DIM_OFFSET_FRACTION",
    "DIM_OFFSET_MIN",
    "DIM_SMOOTHING_PX",
    "OtsuSplit",
    "frame_departure",
    "frame_has_contrast",
    "otsu",
    "threshold_offset",
    "to_gray",
]

#: The local threshold's offset in a dim frame, as a fraction of the frame's largest departure
#: (:func:`frame_departure`): a pixel is dark when it lies this far under its local mean, and
#: where the window straddles a data area's side that mean lies about halfway between the data
#: area and its quiet zone. A dim tag (18–23 grey levels between them, its frame's departure
#: 18) under sensor noise (σ 6) kept under the full offset of 7 only a broken rim of its
#: outline, and no candidate; at 4 the outline closes. Frames whose departure reaches 35 keep
#: the full offset (``DetectorParams.adaptive_c``).
DIM_OFFSET_FRACTION = 0.2
#: The least offset of the local threshold (grey levels), in the half-resolution search
#: smoothed by :data:`DIM_SMOOTHING_PX`.
DIM_OFFSET_MIN = 4.0
#: The Gaussian (σ, px of the searched image) that smooths a dim frame's local-threshold search
#: (the offset lowered by :func:`threshold_offset`): sensor noise of σ 6 is σ 3 at half
#: resolution, and under an offset of 4 it marked a tenth of a plain wall's pixels dark, specks
#: whose tracing took 25–40 ms more per frame; smoothed so, the noise is about σ 1.2, while the
#: outline of a data area 25 px wide there keeps its corners.
DIM_SMOOTHING_PX = 1.0


def to_gray(image: object) -> NDArray[np.uint8]:
    """Convert an image array to 8-bit grey; raises :class:`DecodeError` for non-images.

    Parameters
    ----------
    image : array_like
        ``(H, W)``, ``(H, W, 1)``, ``(H, W, 3)`` (BGR) or ``(H, W, 4)`` (BGRA) array of uint8,
        uint16 (÷ 257; 12-bit data, maximum < 4096, × 255 / 4095), other integers (shifted to 0
        and scaled by 255 / range when outside 0…255), bool or floats (``[0, 1]`` scaled to
        255, otherwise clipped to ``[0, 255]``; NaN → 0).

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` uint8, C-contiguous; an empty input gives an empty ``(0, 0)`` array.
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


@dataclass(frozen=True)
class OtsuSplit:
    """Otsu's threshold ``level`` of a histogram and the means of the classes below/at and above."""

    level: int
    dark: float
    bright: float

    @property
    def contrast(self) -> float:
        """Grey levels between the two class means."""
        return self.bright - self.dark


def otsu(hist: NDArray[Any]) -> OtsuSplit | None:
    """Otsu threshold of a 256-bin histogram and the means of its two classes.

    Parameters
    ----------
    hist : numpy.ndarray
        ``(256,)`` pixel counts per grey level.

    Returns
    -------
    OtsuSplit or None
        None when the histogram holds fewer than 16 pixels or one class is empty.
    """
    # compiled (ottag_native.histogram), as numpy computed it: the running counts w0 and sums
    # s0 of the grey levels; each split's between-class variance w0·w1·(m0 − m1)² =
    # (total·s0 − s_all·w0)² / (w0·w1), an empty class scoring 0 (below every split with two
    # classes, whose means then differ); the first split of the largest
    out = np.empty(4)
    if not otsu_split(np.ascontiguousarray(hist, dtype=np.float64).ravel(), out):
        return None
    return OtsuSplit(int(out[0]), float(out[1]), float(out[2]))


def frame_departure(gray: NDArray[np.uint8]) -> float:
    """The largest departure of the frame from its surroundings (grey levels).

    Judged on the frame reduced 4× by area (sensor noise averages out) against its local mean
    over 9 × 9 of those pixels (a light gradient cancels): the largest difference.

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.

    Returns
    -------
    float
        Grey levels: under 10 on blank frames with noise σ up to 8, over 100 around a tag 18 px
        wide in good light, 18 around a tag 55 px wide in dim light (contrast a quarter).
    """
    h, w = gray.shape
    small = cv2.resize(gray, (max(w // 4, 1), max(h // 4, 1)), interpolation=cv2.INTER_AREA)
    departure = cv2.absdiff(small, cv2.blur(small, (9, 9)))
    return float(cv2.minMaxLoc(departure)[1])


def threshold_offset(departure: float, adaptive_c: float) -> float:
    """The local threshold's offset for a frame of this departure (grey levels).

    ``adaptive_c``, or in a dim frame :data:`DIM_OFFSET_FRACTION` of its departure
    (:func:`frame_departure`), not under :data:`DIM_OFFSET_MIN`.

    Parameters
    ----------
    departure : float
        The frame's largest departure (:func:`frame_departure`).
    adaptive_c : float
        The offset in a frame of full contrast (``DetectorParams.adaptive_c``).

    Returns
    -------
    float
        Grey levels, at most ``adaptive_c``.
    """
    return min(adaptive_c, max(DIM_OFFSET_MIN, DIM_OFFSET_FRACTION * departure))


def frame_has_contrast(gray: NDArray[np.uint8], min_contrast: float) -> bool:
    """Whether some part of the frame departs from its surroundings by ``min_contrast`` grey levels.

    The global threshold outlines dark print on light ground; on a frame without any (a blank
    wall, a lens cap, a dark room) it splits the sensor noise around its median into some
    20,000 specks, and tracing them cost 60–75 ms per frame (flat grey with noise σ 2–3, the
    frame's whole candidate search otherwise 5–13 ms). Judged on the frame reduced 4× by area
    (sensor noise averages out) against its local mean over 9 × 9 of those pixels (a light
    gradient cancels): the largest difference. Blank frames with noise σ up to 8 stay under
    10 grey levels; a tag 18 px wide (21 cm at 8 m) shows over 100. Otsu's classes of the whole
    frame, judged until 2026-12-03, lie closer than 20 on a frame of a small tag under a weak
    gradient, and the pass was skipped where it found that tag (benchmarks/decode_sweeps.py,
    normal tags at 8 m: 7 of the first 60 scenes lost).

    Parameters
    ----------
    gray : numpy.ndarray
        ``(H, W)`` uint8 frame.
    min_contrast : float
        Grey levels (``DetectorParams.min_contrast``, the least a data area must show).

    Returns
    -------
    bool
        False when nothing departs that far (the global threshold would outline noise).
    """
    return frame_departure(gray) >= min_contrast
