"""Dictionary exports as files: reading one to import, writing one out.

The documents themselves are made and read by ``export_dictionary``/``import_dictionary`` of
:mod:`ottag_db.store.dictionary_files`; this module only moves their text to and from files with
errors a user can act on.
"""

from __future__ import annotations

from pathlib import Path

from ottag_db.errors import DictionaryError
from ottag_db.store.dictionary_files import DictionaryDocument, parse_dictionary

__all__ = ["load_dictionary_file", "read_dictionary_file", "write_dictionary_file"]


def read_dictionary_file(path: Path) -> str:
    """The text of a dictionary export (JSON, UTF-8).

    Parameters
    ----------
    path : Path
        The file to read.

    Returns
    -------
    str
        Its text, to pass to ``import_dictionary``.

    Raises
    ------
    DictionaryError
        When the file cannot be read or is not UTF-8.
    """
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DictionaryError(f"{path}: cannot read ({exc})") from exc


def load_dictionary_file(path: Path) -> DictionaryDocument:
    """Read and validate a dictionary export (as ``dictionary import`` does), no database needed.

    Parameters
    ----------
    path : Path
        The JSON file (format ``ottag-dictionary/1``).

    Returns
    -------
    DictionaryDocument
        The validated dictionary; its ``lookup()`` is the decoder's lookup.

    Raises
    ------
    DictionaryError
        The file cannot be read, is not an export, or a tag is bad (the message names it).
    """
    return parse_dictionary(read_dictionary_file(path), source=str(path))


def write_dictionary_file(path: Path, text: str) -> None:
    """Write a dictionary export (JSON or CSV text) as UTF-8, ending in one newline.

    Parameters
    ----------
    path : Path
        The file to write (replaced if it exists; its folder must exist).
    text : str
        The export as ``export_dictionary`` returns it.

    Raises
    ------
    DictionaryError
        When the file cannot be written.
    """
    try:
        path.write_text(text if text.endswith("\n") else text + "\n", encoding="utf-8")
    except OSError as exc:
        raise DictionaryError(f"{path}: cannot write ({exc.strerror})") from exc
