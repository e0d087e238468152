"""Database helpers for the tests."""

from __future__ import annotations

import sqlite3
from pathlib import Path


def dump_database(path: Path) -> list[str]:
    """The SQL dump of a SQLite file: equal dumps mean an unchanged database."""
    con = sqlite3.connect(path)
    try:
        return list(con.iterdump())
    finally:
        con.close()
