"""Decoding a batch of image and video files against a database or a dictionary file: options,
the detector and lookups loaded once, then one JSON-ready record per image or video frame.

Everything the decoder needs from the database is read in :func:`prepare_decoding` (from a
dictionary file in :func:`prepare_file_decoding`); decoding itself (:func:`decode_images`)
never touches the database.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ottag_db.app.decoding import Camera, annotate_detections, decode_array, decode_file, load_camera
from ottag_db.app.detector import open_detector
from ottag_db.app.dictionary_io import load_dictionary_file
from ottag_db.app.pose_tracking import PoseTracker
from ottag_db.app.video import VIDEO_SUFFIXES, WRITER_SUFFIXES, VideoWriter, input_kind, read_frames
from ottag_db.decode import Detector, DetectorParams
from ottag_db.errors import DecodeError, UsageError
from ottag_db.printing.sheet import parse_length
from ottag_db.store.db import Database
from ottag_db.store.lookups import neighbour_members
from ottag_db.store.queries import order_type_numbers

__all__ = [
    "DecodeOptions",
    "DecodeSetup",
    "FrameProgress",
    "decode_images",
    "decode_inputs",
    "decode_options",
    "prepare_decoding",
    "prepare_file_decoding",
]

#: ``progress(input_path, frames_done, frames_total)`` while a video is read (total 0 when unknown).
FrameProgress = Callable[[Path, int, int], None]


@dataclass(frozen=True)
class DecodeOptions:
    """What to compute besides the detections: pose (``camera`` and ``tag_size_mm`` together),
    annotated drawings (written into ``draw_dir``: ``<stem>_decoded.png`` per image,
    ``<stem>_decoded.mp4`` per video; or the one video input's annotated video ``draw_video``)
    and which video frames to decode (every ``every``-th, from frame 0)."""

    camera: Camera | None = None
    tag_size_mm: float | None = None
    draw_dir: Path | None = None
    draw_video: Path | None = None
    every: int = 1


@dataclass(frozen=True)
class DecodeSetup:
    """A detector and the database facts its output refers to, read once.

    - ``numbers``: order-type id → universal number (None when not numbered);
    - ``near``: with a dictionary, canonical λ of every order type one flip from a member →
      the lowest such member's number (why a rejected reading came close); else empty;
    - ``dictionary``: the dictionary whose members alone decode, or None for every order type.
    """

    detector: Detector
    numbers: dict[int, int | None]
    near: dict[str, int]
    dictionary: str | None


def decode_options(
    camera: Path | None, tag_size: str | None, draw_dir: Path | None = None, *, every: int = 1
) -> DecodeOptions:
    """Check and read the options of ``ottag-db decode``.

    Parameters
    ----------
    camera : Path or None
        Camera intrinsics file (see :func:`ottag_db.app.decoding.load_camera`).
    tag_size : str or None
        Side of the black data area with a unit (``"50mm"``); pose needs it with ``camera``.
    draw_dir : Path or None
        Where annotated drawings go: a path ending in a video suffix (``.mp4``, ``.avi``,
        ``.mkv``, ``.mov``, ``.m4v``) is the annotated video of the one video input; any other
        path is a folder (created by :func:`decode_inputs`).
    every : int
        Decode every ``every``-th video frame (frames 0, N, 2N, …); at least 1.

    Returns
    -------
    DecodeOptions
        The camera read, the tag size in mm, the drawing target and the frame step.

    Raises
    ------
    UsageError
        When only one of ``camera`` and ``tag_size`` is given, the size has no known unit,
        ``every`` is below 1 or the drawing is a video format OpenCV is not asked to write.
    DecodeError
        When the camera file cannot be read.
    """
    if (camera is None) != (tag_size is None):
        raise UsageError("--camera and --tag-size go together (pose needs both)")
    if every < 1:
        raise UsageError(f"--every must be at least 1, got {every}")
    draw_video = None
    if draw_dir is not None and draw_dir.suffix.lower() in VIDEO_SUFFIXES:
        if draw_dir.suffix.lower() not in WRITER_SUFFIXES:
            raise UsageError(f"--draw {draw_dir}: annotated videos are written as {', '.join(sorted(WRITER_SUFFIXES))}")
        draw_dir, draw_video = None, draw_dir
    cam = load_camera(camera) if camera is not None else None
    size_mm = parse_length(tag_size) if tag_size is not None else None
    return DecodeOptions(camera=cam, tag_size_mm=size_mm, draw_dir=draw_dir, draw_video=draw_video, every=every)


def prepare_decoding(
    db: Database, dictionary: str | None = None, *, verify: bool = True, fast: bool = False
) -> DecodeSetup:
    """Load the decoder's lookup and the numbers its output reports from the database.

    Parameters
    ----------
    db : Database
        An open database; only read.
    dictionary : str or None
        Only this dictionary's members decode, reported with their tag numbers; None for every
        stored order type.
    verify : bool
        Check each reading geometrically; False decides by order type alone (the paper's rule).
    fast : bool
        Skip the last-resort candidate passes (``DetectorParams(last_resort_passes=False)``).

    Returns
    -------
    DecodeSetup
        The detector, universal numbers and (with a dictionary) its one-flip neighbours.
    """
    detector = open_detector(
        db, dictionary=dictionary, params=DetectorParams(verify=verify, last_resort_passes=not fast)
    )
    numbers = order_type_numbers(db)
    near = neighbour_members(db, dictionary) if dictionary else {}
    return DecodeSetup(detector=detector, numbers=numbers, near=near, dictionary=dictionary)


def prepare_file_decoding(path: Path, *, verify: bool = True, fast: bool = False) -> DecodeSetup:
    """A detector for the tags of a dictionary file alone (``decode --dictionary-file``), no database.

    The file is validated as ``dictionary import`` validates it; every member is verified
    against exactly the file's points.

    Parameters
    ----------
    path : Path
        A dictionary export (JSON, format ``ottag-dictionary/1``).
    verify : bool
        Check each reading geometrically; False decides by order type alone.
    fast : bool
        Skip the last-resort candidate passes (``DetectorParams(last_resort_passes=False)``).

    Returns
    -------
    DecodeSetup
        The detector, the universal numbers the file gives (``order_type`` in the output is
        the order type's position, from 1, among the file's distinct IDs) and no one-flip neighbours.

    Raises
    ------
    DictionaryError
        The file cannot be read or a tag is bad (the message names it).
    """
    doc = load_dictionary_file(path)
    detector = open_detector(dictionary_file=doc, params=DetectorParams(verify=verify, last_resort_passes=not fast))
    return DecodeSetup(detector=detector, numbers=doc.universal_numbers(), near={}, dictionary=doc.name)


def decode_images(setup: DecodeSetup, images: Iterable[Path], options: DecodeOptions) -> Iterator[dict[str, Any]]:
    """Decode image files one after the other (``decode --json`` prints the records as they come).

    Parameters
    ----------
    setup : DecodeSetup
        From :func:`prepare_decoding`.
    images : iterable of Path
        Image files.
    options : DecodeOptions
        Pose and drawings; ``draw_dir`` is created before the first image.

    Returns
    -------
    Iterator[dict]
        Per image the record of :func:`ottag_db.app.decoding.decode_file` (``"error"`` for an
        unreadable file instead of an exception); with a dictionary each rejection also has
        ``one_flip_from_tag``: the member number its reading was one flip from, or None.
    """
    if options.draw_dir is not None:
        options.draw_dir.mkdir(parents=True, exist_ok=True)
    for path in images:
        record = decode_file(
            setup.detector,
            path,
            camera=options.camera,
            tag_size=options.tag_size_mm,
            draw_dir=options.draw_dir,
            numbers=setup.numbers,
        )
        _mark_near_misses(setup, record)
        yield record


def _mark_near_misses(setup: DecodeSetup, record: dict[str, Any]) -> None:
    """With a dictionary, give each rejection the member its reading was one flip from (or None)."""
    if setup.dictionary:
        for r in record.get("rejections", []):
            r["one_flip_from_tag"] = setup.near.get(r["lambda"]) if r["lambda"] else None


def decode_inputs(
    setup: DecodeSetup,
    inputs: Sequence[Path],
    options: DecodeOptions,
    progress: FrameProgress | None = None,
) -> Iterator[dict[str, Any]]:
    """Decode image and video files one after the other: one record per image, one per frame.

    A file is a video when OpenCV does not recognise it as an image (see
    :func:`ottag_db.app.video.input_kind`); every frame goes through the same detector.

    Parameters
    ----------
    setup : DecodeSetup
        From :func:`prepare_decoding`.
    inputs : sequence of Path
        Image and video files.
    options : DecodeOptions
        Pose, drawings and the frame step; ``draw_dir`` is created before the first input.
    progress : callable or None
        ``progress(path, frames_done, frames_total)`` while a video is read (total 0 when the
        container does not say).

    Returns
    -------
    Iterator[dict]
        Per image the record of :func:`decode_images`; per decoded video frame the same keys
        plus ``"frame"`` (0-based index in the video) and ``"time_s"`` (seconds, or None). A
        video that cannot be opened gives one ``{"image", "error"}`` record.

    Raises
    ------
    UsageError
        When ``options.draw_video`` is set and the inputs are not exactly one video.
    """
    if options.draw_video is not None and (len(inputs) != 1 or input_kind(inputs[0]) != "video"):
        raise UsageError(
            f"--draw {options.draw_video} writes the annotated video of exactly one video input; "
            "use --draw DIR for images or several files"
        )
    if options.draw_dir is not None:
        options.draw_dir.mkdir(parents=True, exist_ok=True)
    for path in inputs:
        if input_kind(path) == "image":
            yield from decode_images(setup, [path], options)
            continue
        target = options.draw_video
        if target is None and options.draw_dir is not None:
            target = options.draw_dir / (path.stem + "_decoded.mp4")
        try:
            yield from _decode_video(setup, path, options, target, progress)
        except DecodeError as exc:
            yield {"image": str(path), "error": str(exc)}


def _decode_video(
    setup: DecodeSetup, path: Path, options: DecodeOptions, target: Path | None, progress: FrameProgress | None
) -> Iterator[dict[str, Any]]:
    """The frame records of one video (see :func:`decode_inputs`); raises :class:`DecodeError`."""
    writer: VideoWriter | None = None
    report = None if progress is None else (lambda done, total: progress(path, done, total))
    tracker = PoseTracker()  # ambiguous poses chosen by the video's previous frames
    try:
        for frame in read_frames(path, every=options.every, progress=report):
            fields, detections = decode_array(
                setup.detector, frame.image, camera=options.camera, tag_size=options.tag_size_mm, numbers=setup.numbers
            )
            tracker.track_record(frame.index, fields)
            record: dict[str, Any] = {"image": str(path), "frame": frame.index, "time_s": frame.time_s, **fields}
            _mark_near_misses(setup, record)
            if target is not None:
                if writer is None:
                    writer = VideoWriter(target, (frame.fps or 0.0) / options.every)
                writer.write(annotate_detections(frame.image, detections))
            yield record
    finally:
        if writer is not None:
            writer.close()
