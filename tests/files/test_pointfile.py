"""Tests of ottag_db.files.pointfile: reading, writing, streaming and validation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ottag_db.errors import PointFileError, UsageError
from ottag_db.files.bundled import bundled_point_files
from ottag_db.files.pointfile import (
    OFFICIAL_RECORD_COUNTS,
    file_sha256,
    inspect_point_file,
    iter_point_chunks,
    read_point_file,
    write_point_file,
)
from tests.support.sources import POINT_SET_SOURCES


def test_round_trip_b08_and_b16(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    small = rng.integers(0, 256, size=(10, 6, 2))
    write_point_file(tmp_path / "a.b08", small)
    assert (tmp_path / "a.b08").stat().st_size == 10 * 6 * 2
    assert np.array_equal(read_point_file(tmp_path / "a.b08", n=6), small)
    big = rng.integers(0, 65536, size=(7, 10, 2))
    write_point_file(tmp_path / "b.b16", big)
    raw = (tmp_path / "b.b16").read_bytes()
    assert raw[:2] == int(big[0, 0, 0]).to_bytes(2, "little")
    assert np.array_equal(read_point_file(tmp_path / "b.b16", n=10), big)


def test_streaming_chunks_cover_the_file(tmp_path: Path) -> None:
    pts = np.random.default_rng(1).integers(0, 65536, size=(1000, 9, 2))
    write_point_file(tmp_path / "c.b16", pts)
    info = inspect_point_file(tmp_path / "c.b16", n=9)
    chunks = list(iter_point_chunks(info, chunk_records=128))
    assert [first for first, _ in chunks] == list(range(0, 1000, 128))
    assert np.array_equal(np.concatenate([c for _, c in chunks]), pts)


@pytest.fixture(params=POINT_SET_SOURCES)
def official_dir(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    """A folder with ``otypes03.b08`` … ``otypes08.b08``: the bundled records under the official
    names (same record counts), or Aichholzer's files as the extra layer."""
    if request.param == "reference":
        otdb: Path = request.getfixturevalue("otdb_dir")
        return otdb
    for path, k in bundled_point_files():
        (tmp_path / f"otypes{k:02d}.b08").write_bytes(path.read_bytes())
    return tmp_path


def test_official_names_give_n(official_dir: Path) -> None:
    for k in range(3, 9):
        info = inspect_point_file(official_dir / f"otypes{k:02d}.b08")
        assert (info.n, info.bits, info.records, info.official) == (k, 8, OFFICIAL_RECORD_COUNTS[k], True)


def test_bundled_names_give_n() -> None:
    for path, k in bundled_point_files():
        info = inspect_point_file(path)
        assert (info.n, info.bits, info.records, info.official) == (k, 8, OFFICIAL_RECORD_COUNTS[k], False)


def test_sha256(tmp_path: Path) -> None:
    p = tmp_path / "x.b08"
    p.write_bytes(b"\x00\x01\x02\x03\x04\x05")
    assert file_sha256(p) == "17e88db187afd62c16e5debf3e6527cd006bc012bc90b51a810cd80c2d511f43"


@pytest.mark.parametrize(
    ("name", "content", "n", "message"),
    [
        ("empty.b08", b"", 3, "the file is empty"),
        ("odd.b08", b"\x00" * 7, 3, "not a multiple of the record size 6"),
        ("noname.b08", b"\x00" * 12, None, "pass --points N"),
        ("wrong.txt", b"\x00" * 12, 3, "unknown point-set file type"),
        ("otypes05.b08", b"\x00" * 20, None, "holds 2 records but the official file for n = 5 has 3"),
        ("many.b08", b"\x00" * 22, 11, "unsupported number of points"),
    ],
)
def test_bad_files(tmp_path: Path, name: str, content: bytes, n: int | None, message: str) -> None:
    p = tmp_path / name
    p.write_bytes(content)
    with pytest.raises(PointFileError, match=message) as err:
        inspect_point_file(p, n)
    assert name in str(err.value)


def test_missing_file_and_directory(tmp_path: Path) -> None:
    with pytest.raises(PointFileError, match="no such file"):
        inspect_point_file(tmp_path / "nope.b08", 3)
    (tmp_path / "dir.b08").mkdir()
    with pytest.raises(PointFileError, match="is a directory"):
        inspect_point_file(tmp_path / "dir.b08", 3)


def test_write_rejects_out_of_range(tmp_path: Path) -> None:
    with pytest.raises(PointFileError, match="0 … 255"):
        write_point_file(tmp_path / "x.b08", np.array([[[0, 0], [300, 1], [2, 5]]]))


def test_the_official_name_is_authoritative(tmp_path: Path) -> None:
    p = tmp_path / "otypes05.b08"
    p.write_bytes(b"\x00" * 30)
    with pytest.raises(
        UsageError, match="the name says 5 points per record, which is authoritative, but --points is 6"
    ):
        inspect_point_file(p, 6)
    with pytest.raises(UsageError, match="the name says 7"):
        inspect_point_file(next(path for path, k in bundled_point_files() if k == 7), 5)


@pytest.mark.parametrize(
    ("head", "kind"),
    [
        (b"\x89PNG\r\n\x1a\n", "a PNG image"),
        (b"\xff\xd8\xff\xe0\x00\x10JFIF", "a JPEG image"),
        (b"%PDF-1.7\n", "a PDF document"),
        (b"PK\x03\x04", "a ZIP archive"),
    ],
)
def test_other_formats_are_not_point_files(tmp_path: Path, head: bytes, kind: str) -> None:
    p = tmp_path / "otypes03.b08"
    p.write_bytes(head + b"\x00" * (60 - len(head)))
    with pytest.raises(PointFileError, match=f"not a point-set file \\(its content is {kind}\\)"):
        inspect_point_file(p)
