"""``ottag-db import --k K``: bundled files by point count (k = 9 only on request), and stats."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from click.testing import CliRunner

from ottag_db.cli import cli
from ottag_db.files.bundled import bundled_files_available, bundled_point_files


def test_import_k_selects_bundled_files(runner: CliRunner, tmp_path: Path) -> None:
    db = str(tmp_path / "a.sqlite")
    res = runner.invoke(cli, ["import", "--db", db, "--quiet", "--k", "6", "--k", "5"])
    assert res.exit_code == 0, res.output
    assert [line.split(":")[0] for line in res.stdout.splitlines()[:2]] == ["ottag-k05.b08", "ottag-k06.b08"]
    stats = json.loads(runner.invoke(cli, ["stats", "--db", db, "--json"]).stdout)
    assert sorted(stats) == ["5", "6"]
    assert stats["6"]["complete"] is True and stats["6"]["order_types"] == 20


def test_import_k_without_a_bundled_file_is_one_line(runner: CliRunner, tmp_path: Path) -> None:
    db = tmp_path / "a.sqlite"
    shipped = {k for _p, k, _default in bundled_files_available()}
    missing = 10 if 9 in shipped else 9
    res = runner.invoke(cli, ["import", "--db", str(db), "--k", str(missing)])
    assert res.exit_code == 1
    assert res.stderr.count("\n") == 1 and f"no file for k = {missing}" in res.stderr
    assert not db.exists()  # a bad file list creates no database


def test_import_k_with_named_files_is_a_usage_error(runner: CliRunner, tmp_path: Path) -> None:
    named = tmp_path / "x.b08"
    shutil.copy(next(p for p, k in bundled_point_files() if k == 5), named)
    res = runner.invoke(cli, ["import", "--db", str(tmp_path / "a.sqlite"), str(named), "--points", "5", "--k", "9"])
    assert res.exit_code == 2
    assert "--k selects bundled files" in res.stderr


def test_stats_text_marks_an_incomplete_k(runner: CliRunner, tmp_path: Path) -> None:
    db = str(tmp_path / "a.sqlite")
    named = tmp_path / "some.b08"
    shutil.copy(next(p for p, k in bundled_point_files() if k == 7), named)
    assert runner.invoke(cli, ["import", "--db", db, "--quiet", str(named), "--points", "7"]).exit_code == 0
    out = runner.invoke(cli, ["stats", "--db", db]).stdout
    assert "(not all: 242 exist, 135 up to reflection)" in out  # 135 of 242 stored: the mirrors are missing
