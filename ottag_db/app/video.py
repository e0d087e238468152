"""Video files for ``decode``: telling videos from images, reading frames, writing annotated video.

A file is an **image** when OpenCV recognises an image format by its first bytes
(``cv2.haveImageReader``); otherwise it is tried as a **video** with ``cv2.VideoCapture``
(FFmpeg: MP4, AVI, MKV, MOV, WebM, …). A file neither opens is one error naming it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.errors import DecodeError, UsageError

__all__ = [
    "IMAGE_SUFFIXES",
    "VIDEO_SUFFIXES",
    "WRITER_SUFFIXES",
    "Frame",
    "VideoTally",
    "VideoWriter",
    "input_kind",
    "read_frames",
]

#: File name endings taken for videos in messages and by ``--draw`` (decoding decides by content).
VIDEO_SUFFIXES = frozenset(
    {".mp4", ".m4v", ".mov", ".avi", ".mkv", ".webm", ".mpg", ".mpeg", ".wmv", ".flv", ".ts", ".mts", ".3gp", ".ogv"}
)

#: File name endings of the image formats OpenCV reads: such a file is read as an image whatever
#: its first bytes hold, so a damaged or mislabelled one is refused as an image (FFmpeg would
#: open some of them, e.g. a text file named ``.png``, and find no frame in it).
IMAGE_SUFFIXES = frozenset(
    {".png", ".jpg", ".jpeg", ".jpe", ".tif", ".tiff", ".bmp", ".dib", ".webp", ".pbm", ".pgm", ".ppm", ".pnm", ".pxm"}
    | {".sr", ".ras", ".jp2", ".exr", ".hdr", ".pic", ".avif"}
)

#: Annotated-video endings ``--draw OUT`` writes, with the FourCC each is written with.
WRITER_SUFFIXES: dict[str, str] = {".mp4": "mp4v", ".m4v": "mp4v", ".mov": "mp4v", ".mkv": "mp4v", ".avi": "MJPG"}

# FFmpeg's own log (e.g. "moov atom not found") would add lines to our one-line errors. OpenCV
# reads this variable when it first starts FFmpeg (so it is set on import); a value the user set wins.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

#: Frame rate of an annotated video whose source does not report one, frames per second.
_DEFAULT_FPS = 25.0


@dataclass(frozen=True)
class Frame:
    """One decoded video frame.

    Attributes
    ----------
    index : int
        0-based position in the video (skipped frames count).
    time_s : float or None
        Presentation time, seconds from the first frame: the capture's timestamp, else
        ``index / fps``; None when the video reports neither.
    image : ndarray
        The pixels as OpenCV delivers them (BGR, 8 bit).
    fps : float or None
        The video's frame rate, frames per second (None when it does not say).
    """

    index: int
    time_s: float | None
    image: NDArray[Any]
    fps: float | None = None


def input_kind(path: str | os.PathLike[str]) -> Literal["image", "video"]:
    """Whether ``decode`` reads a file as an image or as a video.

    Parameters
    ----------
    path : str or PathLike
        The input file.

    Returns
    -------
    {"image", "video"}
        ``"image"`` when OpenCV recognises an image format by the file's first bytes, when the
        name ends as an image file does (:data:`IMAGE_SUFFIXES`), or when the path is missing
        or not a file (the image reader reports each fault); ``"video"`` otherwise.
    """
    p = Path(path)
    if not p.is_file() or p.suffix.lower() in IMAGE_SUFFIXES or cv2.haveImageReader(str(p)):
        return "image"
    return "video"


def _open_capture(path: Path) -> Any:
    """Open ``path`` with FFmpeg's reader, quietly; raises :class:`DecodeError` when it cannot."""
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        opened = cap.isOpened()
    finally:
        cv2.utils.logging.setLogLevel(level)
    if not opened:
        if path.suffix.lower() in VIDEO_SUFFIXES:
            raise DecodeError(f"{path}: cannot open the video (damaged file or a codec OpenCV's FFmpeg lacks)")
        raise DecodeError(
            f"{path}: neither an image nor a video OpenCV can read (PNG, JPEG, TIFF, BMP, …; MP4, AVI, MKV, …)"
        )
    return cap


def read_frames(
    path: str | os.PathLike[str],
    *,
    every: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> Iterator[Frame]:
    """Read every ``every``-th frame of a video (frames 0, N, 2N, …); skipped ones are not decoded.

    Parameters
    ----------
    path : str or PathLike
        A video file ``cv2.VideoCapture`` opens.
    every : int
        Keep one frame in ``every`` (≥ 1).
    progress : callable or None
        ``progress(frames_read, total)`` after each frame read or skipped; ``total`` is the
        frame count the container announces, 0 when unknown.

    Returns
    -------
    Iterator[Frame]
        The frames kept, in order. Raises :class:`DecodeError` when the file cannot be opened
        or not a single frame can be read.
    """
    if every < 1:
        raise UsageError(f"--every must be at least 1, got {every}")
    p = Path(path)
    cap = _open_capture(p)
    try:
        count = cap.get(cv2.CAP_PROP_FRAME_COUNT)
        total = int(count) if math.isfinite(count) and count > 0 else 0
        fps = cap.get(cv2.CAP_PROP_FPS)
        fps = fps if math.isfinite(fps) and fps > 0 else 0.0
        index = 0
        while cap.grab():
            if index % every == 0:
                ok, image = cap.retrieve()
                if not ok or image is None:
                    break
                msec = cap.get(cv2.CAP_PROP_POS_MSEC)
                if math.isfinite(msec) and (msec > 0 or index == 0):
                    time_s: float | None = msec / 1000.0
                else:
                    time_s = index / fps if fps else None
                yield Frame(index, None if time_s is None else round(time_s, 6), np.asarray(image), fps or None)
            index += 1
            if progress is not None:
                progress(index, max(total, index) if total else 0)
    finally:
        cap.release()
    if index == 0:
        raise DecodeError(f"{p}: the video opened but no frame could be read (damaged file?)")


class VideoWriter:
    """An annotated video, opened at the first frame (its size fixes the video's).

    Parameters
    ----------
    path : Path
        Output file; its ending chooses the codec (:data:`WRITER_SUFFIXES`).
    fps : float
        Frame rate written, frames per second (the default rate when not positive).
    """

    def __init__(self, path: Path, fps: float):
        codec = WRITER_SUFFIXES.get(path.suffix.lower())
        if codec is None:
            raise UsageError(f"{path}: annotated videos are written as {', '.join(sorted(WRITER_SUFFIXES))}")
        self.path = path
        self.fps = fps if math.isfinite(fps) and fps > 0 else _DEFAULT_FPS
        self.codec = codec
        self._writer: Any = None
        self.frames = 0

    def write(self, canvas: NDArray[Any]) -> None:
        """Append one BGR frame (every frame must have the first one's size).

        Parameters
        ----------
        canvas : ndarray, shape (h, w, 3), uint8
            The annotated frame.
        """
        if self._writer is None:
            h, w = canvas.shape[:2]
            self.path.parent.mkdir(parents=True, exist_ok=True)
            writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter.fourcc(*self.codec), self.fps, (w, h), True)
            if not writer.isOpened():
                raise DecodeError(f"{self.path}: OpenCV cannot write this video (codec {self.codec})")
            self._writer = writer
        self._writer.write(canvas)
        self.frames += 1

    def close(self) -> None:
        """Finish the file (nothing is written when no frame came)."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None


@dataclass
class VideoTally:
    """What the human-readable ``decode`` output says about one video, gathered frame by frame.

    Attributes
    ----------
    image : str
        The video file.
    frames : int
        Frame records seen.
    with_tags : int
        Frames with at least one detection.
    rejected : int
        Rejected candidates over all frames.
    first_s, last_s : float or None
        Time of the first and last frame seen, seconds.
    tags : dict
        Per tag (``(k, order type id, number, tag, polarity, lambda)``) its margin in each frame
        it was seen in, px.
    seen : dict
        Per tag the times of those frames, seconds (None when unknown).
    """

    image: str
    frames: int = 0
    with_tags: int = 0
    rejected: int = 0
    first_s: float | None = None
    last_s: float | None = None
    tags: dict[tuple[Any, ...], list[float]] = field(default_factory=dict)
    seen: dict[tuple[Any, ...], list[float | None]] = field(default_factory=dict)

    def add(self, record: dict[str, Any]) -> None:
        """Count one frame record of :func:`ottag_db.app.decode_batch.decode_inputs`.

        Parameters
        ----------
        record : dict
            A frame object (``"frame"``, ``"time_s"``, ``"detections"``, ``"rejected"``).
        """
        self.frames += 1
        t = record.get("time_s")
        if self.first_s is None:
            self.first_s = t
        self.last_s = t
        self.rejected += int(record.get("rejected", 0))
        dets = record.get("detections", [])
        self.with_tags += bool(dets)
        for d in dets:
            key = (d["k"], d["order_type"], d["number"], d["tag"], d["polarity"], d["lambda"])
            self.tags.setdefault(key, []).append(float(d["margin_px"]))
            self.seen.setdefault(key, []).append(t)

    def lines(self) -> list[str]:
        """The summary: one line for the video, one per tag seen (most frames first).

        Returns
        -------
        list of str
            Lines to print.
        """
        span = ""
        if self.first_s is not None and self.last_s is not None:
            span = f", {self.first_s:.2f}–{self.last_s:.2f} s"
        out = [
            f"{self.image}: {self.frames} frame(s) decoded{span}; {self.with_tags} with tags, "
            f"{self.frames - self.with_tags} without; {self.rejected} rejected candidate(s)"
        ]
        for key, margins in sorted(self.tags.items(), key=lambda kv: (-len(kv[1]), kv[0][1] or 0)):
            k, ot, number, tag, polarity, lam = key
            times = [t for t in self.seen[key] if t is not None]
            when = f" ({min(times):.2f}–{max(times):.2f} s)" if times else ""
            tag_text = f" tag {tag}" if tag is not None else ""
            out.append(
                f"  k={k} #{ot} number {number}{tag_text} {polarity}: in {len(margins)} frame(s){when}, "
                f"margin median {float(np.median(margins)):.2f} px  {lam}"
            )
        return out
