"""Tests of ottag_db.app.dictionary_io: dictionary exports to and from files."""

from __future__ import annotations

from pathlib import Path

import pytest

from ottag_db.app.dictionary_io import read_dictionary_file, write_dictionary_file
from ottag_db.errors import DictionaryError


def test_write_ends_in_one_newline_and_reads_back(tmp_path: Path) -> None:
    out = tmp_path / "d.json"
    write_dictionary_file(out, '{"a": 1}')
    assert out.read_bytes() == b'{"a": 1}\n'
    write_dictionary_file(out, "x,y\n1,2\n")
    assert read_dictionary_file(out) == "x,y\n1,2\n"


def test_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(DictionaryError, match=r"nodir/d\.json: cannot write \(No such file or directory\)"):
        write_dictionary_file(tmp_path / "nodir" / "d.json", "{}")
    with pytest.raises(DictionaryError, match=r"missing\.json: cannot read"):
        read_dictionary_file(tmp_path / "missing.json")
    bad = tmp_path / "latin1.json"
    bad.write_bytes(b"\xff\xfe{")
    with pytest.raises(DictionaryError, match="cannot read"):
        read_dictionary_file(bad)
