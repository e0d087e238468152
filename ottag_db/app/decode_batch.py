"""Decoding a batch of image files against a database: options, the detector and lookups
loaded once, then one JSON-ready record per image.

Everything the decoder needs from the database is read in :func:`prepare_decoding`; decoding
itself (:func:`decode_images`) never touches the database.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ottag_db.app.decoding import Camera, decode_file, load_camera
from ottag_db.decode import Detector, DetectorParams
from ottag_db.errors import UsageError
from ottag_db.printing.sheet import parse_length
from ottag_db.store.db import Database
from ottag_db.store.lookups import dictionary_lookup, neighbour_members
from ottag_db.store.queries import order_type_numbers

__all__ = ["DecodeOptions", "DecodeSetup", "decode_images", "decode_options", "prepare_decoding"]


@dataclass(frozen=True)
class DecodeOptions:
    """What to compute besides the detections: pose (``camera`` and ``tag_size_mm`` together)
    and annotated drawings (written into ``draw_dir``)."""

    camera: Camera | None = None
    tag_size_mm: float | None = None
    draw_dir: Path | None = None


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


def decode_options(camera: Path | None, tag_size: str | None, draw_dir: Path | None = None) -> DecodeOptions:
    """Check and read the options of ``ottag-db decode``.

    Parameters
    ----------
    camera : Path or None
        Camera intrinsics file (see :func:`ottag_db.app.decoding.load_camera`).
    tag_size : str or None
        Side of the black data area with a unit (``"50mm"``); pose needs it with ``camera``.
    draw_dir : Path or None
        Folder for annotated drawings (created by :func:`decode_images`).

    Returns
    -------
    DecodeOptions
        The camera read and the tag size in mm.

    Raises
    ------
    UsageError
        When only one of ``camera`` and ``tag_size`` is given, or the size has no known unit.
    DecodeError
        When the camera file cannot be read.
    """
    if (camera is None) != (tag_size is None):
        raise UsageError("--camera and --tag-size go together (pose needs both)")
    cam = load_camera(camera) if camera is not None else None
    size_mm = parse_length(tag_size) if tag_size is not None else None
    return DecodeOptions(camera=cam, tag_size_mm=size_mm, draw_dir=draw_dir)


def prepare_decoding(db: Database, dictionary: str | None = None, *, verify: bool = True) -> DecodeSetup:
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

    Returns
    -------
    DecodeSetup
        The detector, universal numbers and (with a dictionary) its one-flip neighbours.
    """
    detector = Detector(dictionary_lookup(db, dictionary), DetectorParams(verify=verify))
    numbers = order_type_numbers(db)
    near = neighbour_members(db, dictionary) if dictionary else {}
    return DecodeSetup(detector=detector, numbers=numbers, near=near, dictionary=dictionary)


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
        if setup.dictionary:
            for r in record.get("rejections", []):
                r["one_flip_from_tag"] = setup.near.get(r["lambda"]) if r["lambda"] else None
        yield record
