"""Aichholzer's binary point-set files (``.b08`` uint8, ``.b16`` little-endian uint16), streamed."""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.errors import PointFileError, UsageError

__all__ = [
    "OFFICIAL_RECORD_COUNTS",
    "PointFileInfo",
    "file_sha256",
    "inspect_point_file",
    "iter_point_chunks",
    "read_point_file",
    "write_point_file",
]

#: Record counts of the official files ``otypesNN.b08|b16`` for n = 3 … 10.
OFFICIAL_RECORD_COUNTS: dict[int, int] = {
    3: 1,
    4: 2,
    5: 3,
    6: 16,
    7: 135,
    8: 3315,
    9: 158_817,
    10: 14_309_547,
}

_OFFICIAL_NAME = re.compile(r"^otypes(\d{2})\.b(08|16)$")
# Files written by `ottag-db generate`: n from the name, no official record count.
_OTTAG_NAME = re.compile(r"^ottag-k(\d{2})\.b(08|16)$")
_DTYPES: dict[int, np.dtype[Any]] = {8: np.dtype("<u1"), 16: np.dtype("<u2")}

# Signatures of files people mistake for point sets (at least 4 bytes, so a real point file
# starting with such bytes is very unlikely).
_FOREIGN_MAGIC: tuple[tuple[bytes, str], ...] = (
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"\xff\xd8\xff\xe0", "a JPEG image"),
    (b"\xff\xd8\xff\xe1", "a JPEG image"),
    (b"\xff\xd8\xff\xdb", "a JPEG image"),
    (b"\xff\xd8\xff\xee", "a JPEG image"),
    (b"%PDF-", "a PDF document"),
    (b"PK\x03\x04", "a ZIP archive"),
    (b"GIF87a", "a GIF image"),
    (b"GIF89a", "a GIF image"),
    (b"II*\x00", "a TIFF image"),
    (b"MM\x00*", "a TIFF image"),
    (b"SQLite format 3\x00", "an SQLite database"),
    (b"\x1f\x8b\x08", "a gzip archive"),
    (b"BZh9", "a bzip2 archive"),
    (b"\xfd7zXZ\x00", "an xz archive"),
    (b"7z\xbc\xaf\x27\x1c", "a 7-Zip archive"),
    (b"\x7fELF", "an executable"),
    (b"<?xml", "an XML/SVG document"),
    (b"<svg", "an SVG image"),
    (b"<!DOCTYPE", "an HTML page"),
    (b"<html", "an HTML page"),
)


def _foreign_kind(p: Path) -> str | None:
    """What kind of file ``p`` is when its first bytes are another format's signature."""
    try:
        with p.open("rb") as fh:
            head = fh.read(16)
    except OSError as exc:
        raise PointFileError(f"{p}: cannot read the file ({exc.strerror or exc}); check its permissions") from exc
    for magic, kind in _FOREIGN_MAGIC:
        if head.startswith(magic):
            return kind
    if head[4:8] == b"ftyp":
        return "an MP4/MOV video or HEIF image"
    if head.startswith(b"RIFF"):
        return "a RIFF file (WAV/AVI/WebP)"
    return None


@dataclass(frozen=True)
class PointFileInfo:
    """Layout of a point-set file: ``n`` points per record, ``bits`` per coordinate."""

    path: Path
    n: int
    bits: int
    records: int
    official: bool

    @property
    def record_size(self) -> int:
        """Bytes per record."""
        return self.n * 2 * (self.bits // 8)

    @property
    def dtype(self) -> np.dtype[Any]:
        """numpy dtype of one coordinate."""
        return _DTYPES[self.bits]


def inspect_point_file(path: str | os.PathLike[str], n: int | None = None) -> PointFileInfo:
    """Validate a point-set file's name and size and return its layout.

    ``n`` (points per record) comes from the argument or from an official name
    ``otypesNN.b08|b16`` (or ``ottag-kNN.b08|b16`` as written by ``ottag-db generate``);
    the coordinate width from the suffix ``.b08`` / ``.b16``.

    Parameters
    ----------
    path : str or os.PathLike
        The point-set file.
    n : int, optional
        Points per record (3 … 10); taken from the name when None.

    Returns
    -------
    PointFileInfo
        Points per record, bits per coordinate, record count and whether the name is an
        official one (then the record count is checked against the official count).

    Raises
    ------
    PointFileError
        Naming the file and the fix (missing, another format such as a PNG or PDF, wrong
        size, ``n`` unknown).
    UsageError
        ``n`` contradicts the point count in an official name (``otypesNN``, ``ottag-kNN``).
    """
    p = Path(path)
    if not p.exists():
        raise PointFileError(f"{p}: no such file")
    if p.is_dir():
        raise PointFileError(f"{p}: is a directory, not a point-set file")
    suffix = p.suffix.lower()
    if suffix == ".b08":
        bits = 8
    elif suffix == ".b16":
        bits = 16
    else:
        raise PointFileError(
            f"{p}: unknown point-set file type {suffix or '(none)'!r}; expected .b08 (uint8) or "
            ".b16 (little-endian uint16)"
        )
    kind = _foreign_kind(p)
    if kind is not None:
        raise PointFileError(
            f"{p}: not a point-set file (its content is {kind}); expected raw {bits}-bit coordinates "
            f"as in Aichholzer's otypesNN.b{bits:02d}"
        )
    match = _OFFICIAL_NAME.match(p.name.lower())
    official = match is not None
    ours = _OTTAG_NAME.match(p.name.lower())
    name_n = int(match.group(1)) if match else int(ours.group(1)) if ours else None
    if n is None:
        if name_n is None:
            raise PointFileError(f"{p}: cannot tell the number of points per record from the name; pass --points N")
        n = name_n
    elif name_n is not None and name_n != n:
        raise UsageError(
            f"{p}: the name says {name_n} points per record, which is authoritative, but --points is {n}; "
            "drop --points (or rename the file if it really holds another n)"
        )
    if not 3 <= n <= 10:
        raise PointFileError(f"{p}: unsupported number of points per record {n} (supported: 3 … 10)")
    size = p.stat().st_size
    record_size = n * 2 * (bits // 8)
    if size == 0:
        raise PointFileError(f"{p}: the file is empty")
    if size % record_size:
        raise PointFileError(
            f"{p}: size {size} bytes is not a multiple of the record size {record_size} "
            f"({n} points × 2 coordinates × {bits // 8} byte(s)); the file is truncated "
            f"at byte offset {size - size % record_size} or --points is wrong"
        )
    records = size // record_size
    if official and records != OFFICIAL_RECORD_COUNTS[n]:
        raise PointFileError(
            f"{p}: holds {records} records but the official file for n = {n} has "
            f"{OFFICIAL_RECORD_COUNTS[n]}; the file looks truncated or wrong (download it again)"
        )
    return PointFileInfo(path=p, n=n, bits=bits, records=records, official=official)


def iter_point_chunks(info: PointFileInfo, chunk_records: int = 65536) -> Iterator[tuple[int, NDArray[np.int64]]]:
    """Stream the records of a point-set file in chunks.

    Reads ``chunk_records`` records at a time, so memory stays bounded for any file size.

    Parameters
    ----------
    info : PointFileInfo
        The file's layout, from :func:`inspect_point_file`.
    chunk_records : int, optional
        Records per chunk.

    Yields
    ------
    first : int
        Index of the chunk's first record in the file.
    points : ndarray of int64, shape (B, n, 2)
        The records' coordinates (grid units, as stored).

    Raises
    ------
    PointFileError
        When the file changed while reading (a partial record).
    """
    rs = info.record_size
    with info.path.open("rb") as fh:
        start = 0
        while True:
            buf = fh.read(rs * chunk_records)
            if not buf:
                break
            if len(buf) % rs:
                raise PointFileError(
                    f"{info.path}: the file changed while reading; partial record at byte "
                    f"offset {start * rs + len(buf) - len(buf) % rs}"
                )
            arr = np.frombuffer(buf, dtype=info.dtype).reshape(-1, info.n, 2).astype(np.int64)
            yield start, arr
            start += arr.shape[0]


def read_point_file(path: str | os.PathLike[str], n: int | None = None) -> NDArray[np.int64]:
    """Read a whole (small) point-set file.

    Parameters
    ----------
    path : str or os.PathLike
        The point-set file.
    n : int, optional
        Points per record; taken from the name when None (see :func:`inspect_point_file`).

    Returns
    -------
    ndarray of int64, shape (records, n, 2)
        The coordinates (grid units, as stored).
    """
    info = inspect_point_file(path, n)
    chunks = [c for _, c in iter_point_chunks(info)]
    return np.concatenate(chunks, axis=0)


def write_point_file(path: str | os.PathLike[str], points: ArrayLike, bits: int | None = None) -> None:
    """Write point sets as a ``.b08`` / ``.b16`` file.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write (replaced when it exists).
    points : array_like, shape (B, n, 2)
        Non-negative integer coordinates (grid units) that fit the width: 0 … 255 for 8
        bits, 0 … 65535 for 16.
    bits : int, optional
        8 or 16; from the suffix of ``path`` when None.

    Raises
    ------
    PointFileError
        For an unknown width or coordinates that do not fit it.
    """
    p = Path(path)
    if bits is None:
        bits = {".b08": 8, ".b16": 16}.get(p.suffix.lower(), 0)
    if bits not in _DTYPES:
        raise PointFileError(f"{p}: choose .b08 or .b16 (or bits=8/16)")
    arr = np.asarray(points)
    if arr.ndim != 3 or arr.shape[2] != 2:
        raise ValueError(f"expected (B, n, 2) coordinates, got {arr.shape}")
    limit = 255 if bits == 8 else 65535
    if arr.size and (arr.min() < 0 or arr.max() > limit or not np.all(np.equal(np.mod(arr, 1), 0))):
        raise PointFileError(f"{p}: coordinates must be integers in 0 … {limit} for {bits}-bit files")
    p.write_bytes(arr.astype(_DTYPES[bits]).tobytes())


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file, read in 1 MiB blocks.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    str
        The digest in lowercase hex.
    """
    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
