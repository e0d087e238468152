"""End-to-end tests of the ottag-db command line (CliRunner, real SQLite files in tmp_path)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from ottag_db.cli import cli
from tests.support.database import dump_database
from tests.support.paper import FIG8, TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)


@pytest.fixture
def refdb(reference_db_path: Path, tmp_path: Path) -> Path:
    path = tmp_path / "ref.sqlite"
    shutil.copyfile(reference_db_path, path)
    return path


def test_import_summary_and_noop(runner: CliRunner, otdb_dir: Path, tmp_path: Path) -> None:
    db = str(tmp_path / "x.sqlite")
    res = runner.invoke(
        cli, ["import", "--db", db, "--quiet", str(otdb_dir / "otypes06.b08"), str(otdb_dir / "otypes07.b08")]
    )
    assert res.exit_code == 0, res.output
    assert "otypes06.b08: 16 records read, 16 new order types, 16 new realizations" in res.stdout
    assert "total: 151 records read, 151 new order types" in res.stdout
    assert res.stderr == ""
    res = runner.invoke(cli, ["import", "--db", db, str(otdb_dir / "otypes07.b08")])
    assert res.exit_code == 0
    assert "already imported" in res.stdout


def test_with_mirrors_counts(runner: CliRunner, otdb_dir: Path, tmp_path: Path) -> None:
    db = str(tmp_path / "m.sqlite")
    files = [str(otdb_dir / f"otypes{k:02d}.b08") for k in range(3, 9)]
    res = runner.invoke(cli, ["import", "--db", db, "-q", "--with-mirrors", *files])
    assert res.exit_code == 0, res.output
    stats = json.loads(runner.invoke(cli, ["stats", "--db", db, "--json"]).stdout)
    assert {k: v["order_types"] for k, v in stats.items()} == {"3": 1, "4": 2, "5": 3, "6": 20, "7": 242, "8": 6405}


def test_stats_json_contract(runner: CliRunner, refdb: Path) -> None:
    res = runner.invoke(cli, ["stats", "--db", str(refdb), "--json"])
    assert res.exit_code == 0
    stats = json.loads(res.stdout)
    assert {k: v["order_types"] for k, v in stats.items()} == {"3": 1, "4": 2, "5": 3, "6": 16, "7": 135, "8": 3315}
    assert [stats[str(k)]["unique_min"] for k in (5, 6, 7, 8)] == [2, 11, 131, 3303]
    mp8 = stats["8"]["mp_at_least"]
    assert list(mp8) == [f"{0.5 * i:.1f}" for i in range(1, 19)]
    assert list(mp8.values()) == [3315, 3296, 1240, 642, 371, 231, 135, 83, 56, 37, 26, 15, 10, 6, 5, 4, 3, 3]
    assert list(stats["7"]["mp_at_least"].values()) == [135] * 5 + [86, 60, 47, 32, 26, 18, 15, 8, 7, 4, 3, 3, 3]


def test_stats_table_shows_paper_beside(runner: CliRunner, refdb: Path) -> None:
    res = runner.invoke(cli, ["stats", "--db", str(refdb)])
    assert res.exit_code == 0
    assert "paper8" in res.stdout
    line = next(x for x in res.stdout.splitlines() if x.startswith("6.0"))
    assert line.split()[-4:] == ["3", "16", "15", "15"]


def test_show_by_text_and_id(runner: CliRunner, refdb: Path) -> None:
    res = runner.invoke(cli, ["show", "--db", str(refdb), TABLE9_TEXT])
    assert res.exit_code == 0, res.output
    assert "206,159 214,127 176,49 42,144 47,175 129,178 149,206" in res.stdout
    assert "  - 5 4 3 2 1 0" in res.stdout and "  5 4 3 2 1 0 -" in res.stdout
    assert "hull size   6" in res.stdout
    ident = next(x.split()[1] for x in res.stdout.splitlines() if x.startswith("id "))
    res2 = runner.invoke(cli, ["show", "--db", str(refdb), ident, "--json"])
    data = json.loads(res2.stdout)
    assert data["lambda"] == TABLE9_TEXT and data["lambda_matrix"] == TABLE9
    missing = runner.invoke(cli, ["show", "--db", str(refdb), "99999"])
    assert missing.exit_code == 1 and "no order type with id 99999" in missing.stderr
    bad = runner.invoke(cli, ["show", "--db", str(refdb), "7:12"])
    assert bad.exit_code == 2 and "expected 49 digits" in bad.stderr


def test_id_json_contract(runner: CliRunner, refdb: Path) -> None:
    pts = " ".join(f"{x},{y}" for x, y in FIG8)
    res = runner.invoke(cli, ["id", "--db", str(refdb), pts, "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["k"] == 5 and data["unique_min"] is True and data["in_database"] is True
    assert isinstance(data["id"], int)
    assert data["lambda"].startswith("5:") and data["lambda"][2:].endswith("30120")
    res = runner.invoke(
        cli, ["id", "--db", str(refdb), "0,0 100,3 203,11 250,90 240,200 150,260 40,230 80,120 170,141", "--json"]
    )
    assert res.exit_code == 0
    assert json.loads(res.stdout)["in_database"] is False and json.loads(res.stdout)["id"] is None
    res = runner.invoke(cli, ["id", "--db", str(refdb), "0,0 1,1 2,2"])
    assert res.exit_code == 1 and "collinear" in res.stderr
    res = runner.invoke(cli, ["id", "--db", str(refdb), "0,0 1"])
    assert res.exit_code == 2 and "cannot read point" in res.stderr


def test_list_json_contract(runner: CliRunner, refdb: Path) -> None:
    res = runner.invoke(cli, ["list", "--db", str(refdb), "--k", "7", "--k", "8", "--min-mp", "6", "--format", "json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    assert len(rows) == 30  # Table 7: 15 + 15 at v = 6.0
    for r in rows:
        assert {"id", "k", "lambda", "mp", "points", "hull_size", "unique_min", "chiral", "mirror"} <= set(r)
        assert r["mp"] >= 6.0 and len(r["points"]) == r["k"] and r["lambda"].startswith(f"{r['k']}:")
    matchable = json.loads(
        runner.invoke(cli, ["list", "--db", str(refdb), "--k", "8", "--matchable", "--format", "json"]).stdout
    )
    assert len(matchable) == 3303
    csv_out = runner.invoke(cli, ["list", "--db", str(refdb), "--k", "5", "--format", "csv"]).stdout
    assert csv_out.splitlines()[0].startswith("id,k,lambda,mp,points") and len(csv_out.splitlines()) == 4


def test_db_current_and_upgrade(runner: CliRunner, tmp_path: Path) -> None:
    db = str(tmp_path / "d.sqlite")
    res = runner.invoke(cli, ["db", "current", "--db", db])
    assert "current: (empty)" in res.stdout
    res = runner.invoke(cli, ["db", "upgrade", "--db", db])
    assert res.exit_code == 0
    res = runner.invoke(cli, ["db", "current", "--db", db])
    cur = res.stdout.split()[1]
    assert cur == res.stdout.split()[3]


# ----------------------------------------------------------------------------- bad input
def _assert_fails_unchanged(runner: CliRunner, db: Path, args: list[str], code: int, message: str) -> None:
    before = dump_database(db)
    res = runner.invoke(cli, ["import", "--db", str(db), *args])
    assert res.exit_code == code, (res.stdout, res.stderr)
    assert message in res.stderr, res.stderr
    assert dump_database(db) == before


def test_bad_inputs_leave_database_unchanged(runner: CliRunner, refdb: Path, otdb_dir: Path, tmp_path: Path) -> None:
    _assert_fails_unchanged(runner, refdb, [str(tmp_path / "missing.b08")], 1, "missing.b08: no such file")
    (tmp_path / "empty.b08").write_bytes(b"")
    _assert_fails_unchanged(runner, refdb, ["--points", "5", str(tmp_path / "empty.b08")], 1, "the file is empty")
    (tmp_path / "odd.b08").write_bytes(b"\x01" * 13)
    _assert_fails_unchanged(
        runner, refdb, ["--points", "5", str(tmp_path / "odd.b08")], 1, "not a multiple of the record size 10"
    )
    trunc = tmp_path / "trunc" / "otypes08.b08"
    trunc.parent.mkdir()
    trunc.write_bytes((otdb_dir / "otypes08.b08").read_bytes()[: 16 * 3000])
    _assert_fails_unchanged(runner, refdb, [str(trunc)], 1, "looks truncated or wrong")
    collinear = tmp_path / "col.b08"
    collinear.write_bytes(bytes([10, 10, 200, 30, 90, 220, 0, 0, 1, 1, 2, 2]))  # record 1 collinear
    _assert_fails_unchanged(runner, refdb, ["--points", "3", str(collinear)], 1, "record 1 (byte offset 6)")
    unknown = tmp_path / "points.b08"
    unknown.write_bytes(b"\x00" * 30)
    _assert_fails_unchanged(runner, refdb, [str(unknown)], 1, "pass --points N")
    _assert_fails_unchanged(runner, refdb, ["--points", "12", str(unknown)], 2, "Invalid value for '--points'")
    (tmp_path / "adir.b08").mkdir()
    _assert_fails_unchanged(runner, refdb, [str(tmp_path / "adir.b08")], 1, "is a directory")


def test_second_file_failure_keeps_the_first(runner: CliRunner, otdb_dir: Path, tmp_path: Path) -> None:
    db = tmp_path / "two.sqlite"
    bad = tmp_path / "bad.b08"
    bad.write_bytes(b"\x00" * 7)
    res = runner.invoke(
        cli, ["import", "--db", str(db), "-q", "--points", "5", str(otdb_dir / "otypes05.b08"), str(bad)]
    )
    assert res.exit_code == 1
    stats = json.loads(runner.invoke(cli, ["stats", "--db", str(db), "--json"]).stdout)
    assert stats == {"5": stats["5"]} and stats["5"]["order_types"] == 3


def test_corrupt_database(runner: CliRunner, tmp_path: Path, otdb_dir: Path) -> None:
    db = tmp_path / "corrupt.sqlite"
    db.write_bytes(b"garbage" * 100)
    res = runner.invoke(cli, ["import", "--db", str(db), str(otdb_dir / "otypes05.b08")])
    assert res.exit_code == 1
    assert "not an SQLite database" in res.stderr and str(db) in res.stderr
    assert db.read_bytes() == b"garbage" * 100
    res = runner.invoke(cli, ["stats", "--db", str(db)])
    assert res.exit_code == 1


def test_module_entry_point() -> None:
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "ottag_db", "--version"], capture_output=True, text=True, check=True)
    assert "ottag-db" in out.stdout
