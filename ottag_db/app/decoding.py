"""Decoding image files: reading images and cameras, JSON records, pose and annotated drawings."""

from __future__ import annotations

import json
import os
import re
import sys
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.app.pose_tracking import pose_ambiguity_json
from ottag_db.core.placement import tag_placement
from ottag_db.decode import Detection, Detector, estimate_pose, to_gray
from ottag_db.errors import DecodeError, UsageError

__all__ = [
    "Camera",
    "annotate_detections",
    "decode_array",
    "decode_file",
    "detection_json",
    "draw_detections",
    "load_camera",
    "read_image",
]


@dataclass(frozen=True)
class Camera:
    """Pinhole intrinsics: ``matrix`` 3×3 (pixels), ``dist`` OpenCV distortion coefficients."""

    matrix: NDArray[np.float64]
    dist: NDArray[np.float64]


def load_camera(path: str | os.PathLike[str]) -> Camera:
    """Read camera intrinsics; raises :class:`UsageError` for a missing or malformed file.

    Parameters
    ----------
    path : str or PathLike
        JSON (``camera_matrix`` + optional ``dist_coeffs``, or ``fx``, ``fy``, ``cx``, ``cy``) or
        an OpenCV YAML/XML file (``camera_matrix``, ``distortion_coefficients``).

    Returns
    -------
    Camera
        The 3×3 matrix (pixels) and the distortion coefficients (zeros when absent).
    """
    p = Path(path)
    if not p.is_file():
        raise UsageError(f"{p}: camera file not found")
    if p.suffix.lower() in (".yml", ".yaml", ".xml"):
        fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
        try:
            k = fs.getNode("camera_matrix").mat()
            d = fs.getNode("distortion_coefficients").mat()
        finally:
            fs.release()
        if k is None or k.shape != (3, 3):
            raise UsageError(f"{p}: no 3×3 camera_matrix in the OpenCV file")
        return Camera(
            np.asarray(k, dtype=np.float64), np.zeros(5) if d is None else np.asarray(d, dtype=np.float64).ravel()
        )
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UsageError(f"{p}: cannot read the camera JSON ({exc})") from exc
    try:
        if "camera_matrix" in data:
            k = np.asarray(data["camera_matrix"], dtype=np.float64)
        else:
            k = np.array(
                [[data["fx"], 0.0, data["cx"]], [0.0, data["fy"], data["cy"]], [0.0, 0.0, 1.0]], dtype=np.float64
            )
        dist = np.asarray(data.get("dist_coeffs", [0, 0, 0, 0, 0]), dtype=np.float64).ravel()
    except (KeyError, TypeError, ValueError) as exc:
        raise UsageError(f"{p}: needs camera_matrix (3×3) or fx, fy, cx, cy ({exc})") from exc
    if k.shape != (3, 3):
        raise UsageError(f"{p}: camera_matrix must be 3×3")
    return Camera(np.asarray(k, dtype=np.float64), dist)


def read_image(path: str | os.PathLike[str]) -> NDArray[Any]:
    """Read an image file as stored; raises :class:`DecodeError` for a missing, unreadable,
    truncated or damaged file.

    A JPEG or PNG that ends before its last marker (an interrupted copy or download) is refused
    before decoding, where OpenCV would return the top part and only warn. A JPEG damaged
    inside its coded data (libjpeg's "Corrupt JPEG data: …" warning, on which OpenCV still
    returns a partly invented image) is refused too, with one line of ours in place of
    libjpeg's raw text.

    Parameters
    ----------
    path : str or PathLike
        An image file OpenCV reads (PNG, JPEG, TIFF, BMP, …).

    Returns
    -------
    numpy.ndarray
        The pixels as stored: 8/16-bit, grey ``(H, W)``, BGR or BGRA ``(H, W, 3|4)``.
    """
    p = Path(path)
    if not p.exists():
        raise DecodeError(f"{p}: no such file")
    if p.is_dir():
        raise DecodeError(f"{p}: is a directory, not an image")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise DecodeError(f"{p}: cannot read the file ({exc.strerror or exc})") from exc
    damage = _truncation(data)
    if damage is not None:
        raise DecodeError(f"{p}: {damage}; copy or export the file again")
    if data[:2] == b"\xff\xd8":
        img, warning = _imdecode_jpeg(data)
        damage = _jpeg_damage(warning)
        if damage is not None:
            raise DecodeError(
                f"{p}: damaged JPEG (libjpeg: {damage}): part of the picture would be made up; "
                "copy or export the file again"
            )
        if warning:
            sys.stderr.write(warning)  # another libjpeg note (not about damage): pass it on unchanged
    else:
        img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED) if data else None
    if img is None:
        raise DecodeError(f"{p}: not an image OpenCV can read, or a damaged one (PNG, JPEG, TIFF, BMP, …)")
    return np.asarray(img)


#: libjpeg warnings saying the coded data is damaged (the decoded pixels are partly invented).
_JPEG_DAMAGE = re.compile(r"^(Corrupt JPEG data: .*|Premature end of JPEG file.*)$", re.MULTILINE)
#: libjpeg prints its warnings on file descriptor 2: one capture at a time.
_STDERR_LOCK = threading.Lock()


def _imdecode_jpeg(data: bytes) -> tuple[NDArray[Any] | None, str]:
    """Decode JPEG bytes with OpenCV and return what libjpeg printed meanwhile (not shown)."""
    buf = np.frombuffer(data, dtype=np.uint8)
    with _STDERR_LOCK, tempfile.TemporaryFile() as sink:
        sys.stderr.flush()
        saved = os.dup(2)
        try:
            os.dup2(sink.fileno(), 2)
            try:
                img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
            finally:
                os.dup2(saved, 2)
        finally:
            os.close(saved)
        sink.seek(0)
        text = sink.read().decode("utf-8", "replace")
    return img, text


def _jpeg_damage(warning: str) -> str | None:
    """libjpeg's damage warning, shortened (``"bad Huffman code"``), or None."""
    found = _JPEG_DAMAGE.search(warning)
    if found is None:
        return None
    text = found.group(1).strip()
    return text.removeprefix("Corrupt JPEG data: ").strip() or text


#: A JPEG marker inside entropy-coded data: 0xFF not followed by 0x00 (stuffing), RSTn or 0xFF.
_JPEG_MARKER = re.compile(rb"\xff[^\x00\xd0-\xd7\xff]")
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _truncation(data: bytes) -> str | None:
    """Why a JPEG or PNG file is cut short, or None (also for other formats and when unsure)."""
    n = len(data)
    if data[:2] == b"\xff\xd8":
        pos = 2
        while pos + 1 < n:
            if data[pos] != 0xFF:
                return None  # not the structure we know: leave the verdict to the decoder
            marker = data[pos + 1]
            if marker == 0xD9:
                return None
            if marker == 0xFF:
                pos += 1
                continue
            if 0xD0 <= marker <= 0xD7 or marker == 0x01:
                pos += 2
                continue
            if pos + 4 > n:
                break
            pos += 2 + int.from_bytes(data[pos + 2 : pos + 4], "big")
            if marker == 0xDA:  # start of scan: coded data up to the next marker
                found = _JPEG_MARKER.search(data, pos)
                if found is None:
                    break
                pos = found.start()
        return f"truncated JPEG: the file ends after {n} bytes, before the end-of-image marker"
    if data[:8] == _PNG_SIGNATURE:
        pos = 8
        while pos + 8 <= n:
            length = int.from_bytes(data[pos : pos + 4], "big")
            if data[pos + 4 : pos + 8] == b"IEND":
                return None
            pos += 12 + length
        return f"truncated PNG: the file ends after {n} bytes, before the IEND chunk"
    return None


def _arr(a: NDArray[np.float64] | None, digits: int = 3) -> Any:
    return None if a is None else np.round(a, digits).tolist()


def detection_json(
    d: Detection, *, camera: Camera | None = None, tag_size: float | None = None, number: int | None = None
) -> dict[str, Any]:
    """The JSON object of one detection (see the README's contract); pose when asked.

    Parameters
    ----------
    d : Detection
        The detection (its ID goes out under the key ``"lambda"``).
    camera : Camera or None
        Intrinsics; with ``tag_size`` adds ``"pose"``.
    tag_size : float or None
        Data-area side (mm), the unit of the pose's translation.
    number : int or None
        The order type's universal number.

    Returns
    -------
    dict
        JSON-ready values (coordinates rounded to 3 decimals, image pixels).
    """
    out: dict[str, Any] = {
        "lambda": d.lambda_text,
        "k": d.k,
        "order_type": d.order_type_id,
        "number": number,
        "tag": d.tag,
        "polarity": d.polarity,
        "points": _arr(d.points),
        "model_points": _arr(d.model_points),
        "corners": _arr(d.corners),
        "homography": None if d.homography is None else np.asarray(d.homography).tolist(),
        "reprojection_error_px": None if d.reprojection_error_px is None else round(d.reprojection_error_px, 4),
        "margin_px": round(d.margin_px, 4),
        "corrected_flips": d.corrected_flips,
        "model_correlation": None if d.model_correlation is None else round(d.model_correlation, 4),
        "corners_seen": None if d.corners_seen is None else list(d.corners_seen),
    }
    if camera is not None and tag_size is not None:
        placement = None if d.model_points is None else tag_placement(d.model_points)
        pose = estimate_pose(d, camera.matrix, camera.dist, tag_size, placement)
        out["pose"] = {
            "rvec": np.asarray(pose.rvec).ravel().tolist(),
            "tvec": np.asarray(pose.tvec).ravel().tolist(),
            "R": np.asarray(pose.R).tolist(),
            "reprojection_error_px": pose.reprojection_error_px,
            "points_used": pose.n_points,
            "unit": "same as --tag-size (mm)",
            "solutions": [
                {
                    "rvec": np.asarray(s.rvec).ravel().tolist(),
                    "tvec": np.asarray(s.tvec).ravel().tolist(),
                    "reprojection_error_px": s.reprojection_error_px,
                }
                for s in pose.solutions
            ],
            **pose_ambiguity_json(pose),
        }
    return out


def annotate_detections(image: NDArray[Any], detections: list[Detection]) -> NDArray[np.uint8]:
    """The image in grey with data-area outlines, labelled points and IDs drawn in colour.

    Parameters
    ----------
    image : numpy.ndarray
        The decoded image (any array :func:`~ottag_db.decode.to_gray` accepts).
    detections : list of Detection
        What to draw.

    Returns
    -------
    numpy.ndarray, shape (H, W, 3), uint8
        The annotated BGR picture.
    """
    canvas = cv2.cvtColor(to_gray(image), cv2.COLOR_GRAY2BGR)
    for d in detections:
        quad = np.round(d.corners).astype(np.int32)
        cv2.polylines(canvas, [quad], True, (0, 200, 0), 2, cv2.LINE_AA)
        cv2.circle(canvas, tuple(int(v) for v in quad[0]), 5, (0, 0, 255), -1)
        for label, (x, y) in enumerate(d.points):
            c = (round(x), round(y))
            cv2.circle(canvas, c, 3, (255, 80, 0), -1, cv2.LINE_AA)
            cv2.putText(canvas, str(label), (c[0] + 4, c[1] - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 80, 0), 1)
        cx, cy = d.center
        text = f"k={d.k} #{d.order_type_id}" + (f" tag {d.tag}" if d.tag is not None else "") + f" {d.polarity}"
        cv2.putText(canvas, text, (int(cx) - 40, int(cy)), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 255), 1, cv2.LINE_AA)
    return np.asarray(canvas, dtype=np.uint8)


def draw_detections(image: NDArray[Any], detections: list[Detection], out: Path) -> None:
    """Write ``image`` with data-area outlines, labelled points and IDs to ``out``.

    Parameters
    ----------
    image : numpy.ndarray
        The decoded image (any array :func:`~ottag_db.decode.to_gray` accepts).
    detections : list of Detection
        What to draw.
    out : Path
        The image file to write; raises :class:`DecodeError` when it cannot be written.
    """
    if not cv2.imwrite(str(out), annotate_detections(image, detections)):
        raise DecodeError(f"{out}: could not write the drawing")


def decode_array(
    detector: Detector,
    image: NDArray[Any],
    *,
    camera: Camera | None = None,
    tag_size: float | None = None,
    numbers: dict[int, int | None] | None = None,
) -> tuple[dict[str, Any], list[Detection]]:
    """Decode pixels already in memory (an image or a video frame) into the record's fields.

    Parameters
    ----------
    detector : Detector
        The configured detector.
    image : numpy.ndarray
        The pixels (any array :func:`~ottag_db.decode.to_gray` accepts).
    camera, tag_size : Camera, float or None
        Pose for every detection when both are given (see :func:`detection_json`).
    numbers : dict or None
        Order-type id → universal number for the output.

    Returns
    -------
    fields : dict
        ``{"detections", "rejected", "rejections"}`` (the README's contract).
    detections : list of Detection
        The detections themselves (for drawing).
    """
    detections, rejected = detector.detect_with_rejections(image)
    nums = numbers or {}
    fields: dict[str, Any] = {
        "detections": [
            detection_json(
                d, camera=camera, tag_size=tag_size, number=nums.get(d.order_type_id) if d.order_type_id else None
            )
            for d in detections
        ],
        "rejected": len(rejected),
        "rejections": [
            {"reason": r.reason, "polarity": r.polarity, "lambda": r.lambda_text, "detail": r.detail} for r in rejected
        ],
    }
    return fields, detections


def decode_file(
    detector: Detector,
    path: str | os.PathLike[str],
    *,
    camera: Camera | None = None,
    tag_size: float | None = None,
    draw_dir: Path | None = None,
    numbers: dict[int, int | None] | None = None,
) -> dict[str, Any]:
    """Decode one image file into ``{"image", "detections", "rejected"}`` (plus ``"error"``).

    An unreadable file gives a record with ``"error"`` instead of raising, so a batch goes on.

    Parameters
    ----------
    detector : Detector
        The configured detector.
    path : str or PathLike
        The image file.
    camera, tag_size : Camera, float or None
        Pose for every detection when both are given (see :func:`detection_json`).
    draw_dir : Path or None
        Folder for the annotated drawing ``<stem>_decoded.png``.
    numbers : dict or None
        Order-type id → universal number for the output.

    Returns
    -------
    dict
        ``{"image", "detections", "rejected", "rejections"}`` (the README's contract).
    """
    record: dict[str, Any] = {"image": str(path), "detections": [], "rejected": 0}
    try:
        image = read_image(path)
        fields, detections = decode_array(detector, image, camera=camera, tag_size=tag_size, numbers=numbers)
    except DecodeError as exc:
        record["error"] = str(exc)
        return record
    record.update(fields)
    if draw_dir is not None:
        draw_detections(image, detections, draw_dir / (Path(path).stem + "_decoded.png"))
    return record
