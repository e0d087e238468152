"""Tests of ottag_db.files.bundled: which bundled files the default import takes, and --k."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from ottag_db.errors import PointFileError
from ottag_db.files.bundled import DEFAULT_IMPORT_MAX_K, bundled_files_available, bundled_point_files
from ottag_db.files.pointfile import write_point_file
from ottag_db.files.resources import data_dir
from tests.support.k9_sample import nine_point_sets


def _data_folder(tmp_path: Path, *, nine_default: bool | None) -> Path:
    """A data folder like the shipped one: k = 5, 6 copied, a small k = 9 file, a manifest."""
    folder = tmp_path / "data"
    folder.mkdir()
    for k in (5, 6):
        shutil.copy(data_dir() / f"ottag-k0{k}.b08", folder)
    write_point_file(folder / "ottag-k09.b08", nine_point_sets(6))
    manifest = json.loads((data_dir() / "manifest.json").read_text(encoding="utf-8"))
    files = {k: manifest["files"][k] for k in ("5", "6")}
    files["9"] = {"file": "ottag-k09.b08", "points": 9, "records": 6}
    if nine_default is not None:
        files["9"]["default"] = nine_default
    (folder / "manifest.json").write_text(json.dumps({"files": files}), encoding="utf-8")
    return folder


def test_shipped_default_is_three_to_eight() -> None:
    assert [k for _p, k in bundled_point_files()] == [3, 4, 5, 6, 7, 8]
    assert all(default for _p, k, default in bundled_files_available() if k <= DEFAULT_IMPORT_MAX_K)


@pytest.mark.parametrize("nine_default", [False, None])
def test_nine_points_only_on_request(tmp_path: Path, nine_default: bool | None) -> None:
    # "default": false in the manifest, or no key at all: k = 9 stays out of the default import.
    folder = _data_folder(tmp_path, nine_default=nine_default)
    assert [k for _p, k in bundled_point_files(folder=folder)] == [5, 6]
    assert bundled_point_files((9,), folder=folder) == [(folder / "ottag-k09.b08", 9)]
    assert [k for _p, k in bundled_point_files((9, 5, 9), folder=folder)] == [5, 9]


def test_manifest_can_put_a_file_in_the_default(tmp_path: Path) -> None:
    folder = _data_folder(tmp_path, nine_default=True)
    assert [k for _p, k in bundled_point_files(folder=folder)] == [5, 6, 9]


def test_asking_for_a_k_that_is_not_bundled(tmp_path: Path) -> None:
    folder = _data_folder(tmp_path, nine_default=False)
    with pytest.raises(PointFileError, match=r"no file for k = 7 \(bundled: k = 5, 6, 9"):
        bundled_point_files((7, 9), folder=folder)
    with pytest.raises(PointFileError, match="no bundled point-set files"):
        bundled_point_files(folder=tmp_path / "empty")
