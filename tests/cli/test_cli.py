"""End-to-end tests of the ottag-db command line (CliRunner, real SQLite files in tmp_path).

They run on the bundled data (same IDs as Aichholzer's files, other coordinates, mirrors
imported); only the numbers that depend on the reference coordinates (the paper's Table 7
and Fig. 4) need ``$OTTAG_AICHHOLZER_DIR``.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from ottag_db.cli import cli
from ottag_db.files.bundled import bundled_point_files
from tests.support.database import dump_database
from tests.support.paper import FIG4, FIG8, TABLE9

TABLE9_TEXT = "7:" + "".join(str(v) for row in TABLE9 for v in row)
#: Paper, Table 2 (order types up to reflection) and Table 3 (unique minimum, k = 5 … 8).
TABLE2 = {"3": 1, "4": 2, "5": 3, "6": 16, "7": 135, "8": 3315}
TABLE3 = [2, 11, 131, 3303]
#: Every order type of 3 … 8 points, both chiralities (the bundled data with mirrors).
ALL_ORDER_TYPES = {"3": 1, "4": 2, "5": 3, "6": 20, "7": 242, "8": 6405}


def _bundled(k: int) -> Path:
    return next(p for p, kk in bundled_point_files() if kk == k)


@pytest.fixture
def bdb(bundled_db_path: Path, tmp_path: Path) -> Path:
    """A private copy of the bundled database (every order type of 3 … 8 points)."""
    path = tmp_path / "bundled.sqlite"
    shutil.copyfile(bundled_db_path, path)
    return path


def _stats(runner: CliRunner, db: Path | str) -> dict[str, dict[str, object]]:
    res = runner.invoke(cli, ["stats", "--db", str(db), "--json"])
    assert res.exit_code == 0, res.output
    data: dict[str, dict[str, object]] = json.loads(res.stdout)
    return data


def test_import_summary_and_noop(runner: CliRunner, tmp_path: Path) -> None:
    db = str(tmp_path / "x.sqlite")
    res = runner.invoke(cli, ["import", "--db", db, "--quiet", str(_bundled(6)), str(_bundled(7))])
    assert res.exit_code == 0, res.output
    assert "ottag-k06.b08: 16 records read, 16 new order types, 16 new realizations" in res.stdout
    assert "total: 151 records read, 151 new order types" in res.stdout
    assert res.stderr == ""
    res = runner.invoke(cli, ["import", "--db", db, str(_bundled(7))])
    assert res.exit_code == 0
    assert "already imported" in res.stdout
    assert f"database: {db}" in res.stderr


def test_import_without_files_is_the_bundled_data_with_mirrors(
    runner: CliRunner, bundled_db_path: Path, tmp_path: Path
) -> None:
    db = tmp_path / "b.sqlite"
    res = runner.invoke(cli, ["import", "--db", str(db), "-q"])
    assert res.exit_code == 0, res.output
    assert res.stdout.splitlines()[-1] == "total: 3472 records read, 6673 new order types, 6673 new realizations"
    stats = _stats(runner, db)
    assert {k: v["order_types"] for k, v in stats.items()} == ALL_ORDER_TYPES
    assert stats == _stats(runner, bundled_db_path)
    res = runner.invoke(cli, ["import", "--db", str(db), "-q", "--no-mirrors", str(_bundled(5))])
    assert "already imported" in res.stdout


def test_with_mirrors_counts(runner: CliRunner, tmp_path: Path) -> None:
    db = str(tmp_path / "m.sqlite")
    res = runner.invoke(cli, ["import", "--db", db, "-q", "--with-mirrors", str(_bundled(6)), str(_bundled(7))])
    assert res.exit_code == 0, res.output
    assert {k: v["order_types"] for k, v in _stats(runner, db).items()} == {"6": 20, "7": 242}


def test_stats_json_contract(runner: CliRunner, bdb: Path) -> None:
    stats = _stats(runner, bdb)
    assert {k: v["order_types"] for k, v in stats.items()} == ALL_ORDER_TYPES
    up = {k: v["up_to_reflection"] for k, v in stats.items()}
    assert {k: v["order_types"] for k, v in up.items()} == TABLE2  # type: ignore[index]
    assert [up[str(k)]["unique_min"] for k in (5, 6, 7, 8)] == TABLE3  # type: ignore[index]
    for k, v in stats.items():
        assert set(v) == {"order_types", "unique_min", "chiral", "complete", "mp_at_least", "up_to_reflection"}
        assert v["complete"] is True
        for mp in (v["mp_at_least"], up[k]["mp_at_least"]):  # type: ignore[index]
            assert list(mp) == [f"{0.5 * i:.1f}" for i in range(1, 19)]
            counts = list(mp.values())
            assert counts == sorted(counts, reverse=True)
        assert v["mp_at_least"]["0.5"] <= v["order_types"]  # type: ignore[index,operator]


def test_stats_table_shows_paper_beside(runner: CliRunner, bdb: Path) -> None:
    res = runner.invoke(cli, ["stats", "--db", str(bdb)])
    assert res.exit_code == 0
    lines = res.stdout.splitlines()
    assert lines[0].startswith("k  order types")
    assert lines[6].split() == ["8", "6405", "6388", "6180", "|", "3315", "3303"]
    assert "paper8" in res.stdout
    line = next(x for x in lines if x.startswith("6.0"))
    assert line.split()[-4:] == ["3", "16", "15", "15"]  # the paper's Table 7 at v = 6.0
    empty_db = bdb.parent / "empty.sqlite"
    assert runner.invoke(cli, ["db", "upgrade", "--db", str(empty_db)]).exit_code == 0
    empty = runner.invoke(cli, ["stats", "--db", str(empty_db)])
    assert empty.exit_code == 0 and empty.stdout == ""
    assert "holds no order types yet" in empty.stderr


def test_show_by_text_and_id(runner: CliRunner, bdb: Path) -> None:
    res = runner.invoke(cli, ["show", "--db", str(bdb), TABLE9_TEXT])
    assert res.exit_code == 0, res.output
    assert "  - 5 4 3 2 1 0" in res.stdout and "  5 4 3 2 1 0 -" in res.stdout
    assert "hull size   6" in res.stdout
    ident = next(x.split()[1] for x in res.stdout.splitlines() if x.startswith("id "))
    points = next(x for x in res.stdout.splitlines() if x.startswith("points ")).split("[")[0].split(None, 1)[1]
    res2 = runner.invoke(cli, ["show", "--db", str(bdb), ident, "--json"])
    data = json.loads(res2.stdout)
    assert data["lambda"] == TABLE9_TEXT and data["lambda_matrix"] == TABLE9
    assert data["id"] == int(ident) and data["all_realizations"][0]["points"] == data["points"]
    assert " ".join(f"{x},{y}" for x, y in data["points"]) == points.strip()
    # The printed realization has the ID it is shown under.
    again = json.loads(runner.invoke(cli, ["id", "--db", str(bdb), points.strip(), "--json"]).stdout)
    assert again["lambda"] == TABLE9_TEXT and again["id"] == int(ident)
    missing = runner.invoke(cli, ["show", "--db", str(bdb), "99999"])
    assert missing.exit_code == 1 and "no order type with id 99999" in missing.stderr
    bad = runner.invoke(cli, ["show", "--db", str(bdb), "7:12"])
    assert bad.exit_code == 2 and "expected 49 digits" in bad.stderr


def test_id_json_contract(runner: CliRunner, bdb: Path) -> None:
    pts = " ".join(f"{x},{y}" for x, y in FIG8)
    res = runner.invoke(cli, ["id", "--db", str(bdb), pts, "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["k"] == 5 and data["unique_min"] is True and data["in_database"] is True
    assert isinstance(data["id"], int)
    assert data["lambda"].startswith("5:") and data["lambda"][2:].endswith("30120")
    text = runner.invoke(cli, ["id", "--db", str(bdb), pts]).stdout
    assert f"in database yes, id {data['id']}" in text and f"lambda      {data['lambda']}" in text
    res = runner.invoke(
        cli, ["id", "--db", str(bdb), "0,0 100,3 203,11 250,90 240,200 150,260 40,230 80,120 170,141", "--json"]
    )
    assert res.exit_code == 0
    assert json.loads(res.stdout)["in_database"] is False and json.loads(res.stdout)["id"] is None
    res = runner.invoke(cli, ["id", "--db", str(bdb), "0,0 1,1 2,2"])
    assert res.exit_code == 1 and "collinear" in res.stderr
    res = runner.invoke(cli, ["id", "--db", str(bdb), "0,0 1"])
    assert res.exit_code == 2 and "cannot read point" in res.stderr


def test_list_json_contract(runner: CliRunner, bdb: Path) -> None:
    stats = _stats(runner, bdb)
    res = runner.invoke(cli, ["list", "--db", str(bdb), "--k", "7", "--k", "8", "--min-mp", "6", "--format", "json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    assert len(rows) == sum(stats[k]["mp_at_least"]["6.0"] for k in ("7", "8"))  # type: ignore[index]
    for r in rows:
        assert {"id", "k", "lambda", "mp", "points", "hull_size", "unique_min", "chiral", "mirror"} <= set(r)
        assert r["mp"] >= 6.0 and len(r["points"]) == r["k"] and r["lambda"].startswith(f"{r['k']}:")
    matchable = json.loads(
        runner.invoke(cli, ["list", "--db", str(bdb), "--k", "8", "--matchable", "--format", "json"]).stdout
    )
    assert len(matchable) == stats["8"]["unique_min"] == 6388
    res = runner.invoke(cli, ["list", "--db", str(bdb), "--k", "5", "--format", "csv"])
    assert res.stdout.splitlines()[0] == "id,k,lambda,mp,points,hull_size,unique_min,chiral,mirror,number"
    assert len(res.stdout.splitlines()) == 4 and res.stderr == "3 order type(s)\n"
    table = runner.invoke(cli, ["list", "--db", str(bdb), "--k", "5", "-q"])
    assert table.stdout.splitlines()[0].split() == ["id", "number", "k", "MP", "hull", "uniq", "chir", "lambda"]
    assert len(table.stdout.splitlines()) == 4 and table.stderr == ""


def test_reference_tables(runner: CliRunner, reference_db_path: Path, tmp_path: Path) -> None:
    """What depends on Aichholzer's coordinates: the paper's Table 7 and Fig. 4 (the extra layer)."""
    refdb = tmp_path / "ref.sqlite"
    shutil.copyfile(reference_db_path, refdb)
    stats = _stats(runner, refdb)
    assert {k: v["order_types"] for k, v in stats.items()} == TABLE2
    assert [stats[str(k)]["unique_min"] for k in (5, 6, 7, 8)] == TABLE3
    mp8 = stats["8"]["mp_at_least"]
    assert list(mp8.values()) == [3315, 3296, 1240, 642, 371, 231, 135, 83, 56, 37, 26, 15, 10, 6, 5, 4, 3, 3]  # type: ignore[attr-defined]
    assert list(stats["7"]["mp_at_least"].values()) == [135] * 5 + [86, 60, 47, 32, 26, 18, 15, 8, 7, 4, 3, 3, 3]  # type: ignore[attr-defined]
    table = runner.invoke(cli, ["stats", "--db", str(refdb)]).stdout
    line = next(x for x in table.splitlines() if x.startswith("6.0"))
    assert line.split()[1:] == ["3", "16", "15", "15", "3", "16", "15", "15"]  # ours equal the paper's
    res = runner.invoke(cli, ["list", "--db", str(refdb), "--k", "7", "--k", "8", "--min-mp", "6", "--format", "json"])
    assert len(json.loads(res.stdout)) == 30  # Table 7: 15 + 15 at v = 6.0
    res = runner.invoke(cli, ["show", "--db", str(refdb), TABLE9_TEXT])
    assert " ".join(f"{x},{y}" for x, y in FIG4) in res.stdout


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
    assert "Traceback" not in res.output
    assert dump_database(db) == before


def test_bad_inputs_leave_database_unchanged(runner: CliRunner, bdb: Path, tmp_path: Path) -> None:
    _assert_fails_unchanged(runner, bdb, [str(tmp_path / "missing.b08")], 1, "missing.b08: no such file")
    (tmp_path / "empty.b08").write_bytes(b"")
    _assert_fails_unchanged(runner, bdb, ["--points", "5", str(tmp_path / "empty.b08")], 1, "the file is empty")
    (tmp_path / "odd.b08").write_bytes(b"\x01" * 13)
    _assert_fails_unchanged(
        runner, bdb, ["--points", "5", str(tmp_path / "odd.b08")], 1, "not a multiple of the record size 10"
    )
    trunc = tmp_path / "trunc" / "otypes08.b08"
    trunc.parent.mkdir()
    trunc.write_bytes(_bundled(8).read_bytes()[: 16 * 3000])
    _assert_fails_unchanged(runner, bdb, [str(trunc)], 1, "looks truncated or wrong")
    collinear = tmp_path / "col.b08"
    collinear.write_bytes(bytes([10, 10, 200, 30, 90, 220, 0, 0, 1, 1, 2, 2]))  # record 1 collinear
    _assert_fails_unchanged(runner, bdb, ["--points", "3", str(collinear)], 1, "record 1 (byte offset 6)")
    unknown = tmp_path / "points.b08"
    unknown.write_bytes(b"\x00" * 30)
    _assert_fails_unchanged(runner, bdb, [str(unknown)], 1, "pass --points N")
    _assert_fails_unchanged(runner, bdb, ["--points", "12", str(unknown)], 2, "Invalid value for '--points'")
    (tmp_path / "adir.b08").mkdir()
    _assert_fails_unchanged(runner, bdb, [str(tmp_path / "adir.b08")], 1, "is a directory")


def test_second_file_failure_keeps_the_first(runner: CliRunner, tmp_path: Path) -> None:
    db = tmp_path / "two.sqlite"
    bad = tmp_path / "bad.b08"
    bad.write_bytes(b"\x00" * 10)  # a readable file whose record is not in general position
    res = runner.invoke(cli, ["import", "--db", str(db), "-q", "--points", "5", str(_bundled(5)), str(bad)])
    assert res.exit_code == 1
    assert res.stdout.startswith("ottag-k05.b08: 3 records read")
    stats = _stats(runner, db)
    assert stats == {"5": stats["5"]} and stats["5"]["order_types"] == 3
    # A file list with an unreadable name or size is refused before anything is imported.
    (tmp_path / "odd.b08").write_bytes(b"\x00" * 7)
    other = tmp_path / "other.sqlite"
    res = runner.invoke(
        cli, ["import", "--db", str(other), "--points", "5", str(_bundled(5)), str(tmp_path / "odd.b08")]
    )
    assert res.exit_code == 1 and "not a multiple of the record size" in res.stderr and not other.exists()


def test_corrupt_database(runner: CliRunner, tmp_path: Path) -> None:
    db = tmp_path / "corrupt.sqlite"
    db.write_bytes(b"garbage" * 100)
    res = runner.invoke(cli, ["import", "--db", str(db), str(_bundled(5))])
    assert res.exit_code == 1
    assert "not an SQLite database" in res.stderr and str(db) in res.stderr
    assert db.read_bytes() == b"garbage" * 100
    res = runner.invoke(cli, ["stats", "--db", str(db)])
    assert res.exit_code == 1


def test_usage_errors_exit_2_without_traceback(runner: CliRunner, bdb: Path) -> None:
    for args in (["nosuch"], ["show"], ["list", "--format", "xml"], ["list", "--k", "12"]):
        res = runner.invoke(cli, [*args, "--db", str(bdb)] if args[0] == "list" else args)
        assert res.exit_code == 2, args
        assert "Traceback" not in res.output and res.stdout == ""


def test_module_entry_point() -> None:
    out = subprocess.run([sys.executable, "-m", "ottag_db", "--version"], capture_output=True, text=True, check=True)
    assert out.stdout == "ottag-db, version 0.1.0\n"


# ----------------------------------------------------------------------------- issue 11
def test_db_and_quiet_before_or_after_the_command(runner: CliRunner, tmp_path: Path) -> None:
    db = tmp_path / "before.sqlite"
    res = runner.invoke(cli, ["--db", str(db), "--quiet", "import", str(_bundled(5))])
    assert res.exit_code == 0, res.output
    assert res.stdout.startswith("ottag-k05.b08: 3 records read") and res.stderr == ""
    assert _stats(runner, db)["5"]["order_types"] == 3
    after = runner.invoke(cli, ["stats", "--json", "--db", str(db)])
    before = runner.invoke(cli, ["--db", str(db), "stats", "--json"])
    assert before.exit_code == 0 and before.stdout == after.stdout
    # The command's own --db wins over the one before it.
    res = runner.invoke(cli, ["--db", str(tmp_path / "other.sqlite"), "stats", "--json", "--db", str(db)])
    assert res.exit_code == 0 and res.stdout == after.stdout


def test_read_commands_refuse_a_missing_database(
    runner: CliRunner, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    missing = tmp_path / "nothing.sqlite"
    for args in (
        ["stats"],
        ["list"],
        ["show", "1"],
        ["export", "--k", "6", str(tmp_path / "t.pdf")],
        ["render", "1", str(tmp_path / "t.png")],
        ["dictionary", "list"],
        ["sources"],
        ["db", "check"],
    ):
        res = runner.invoke(cli, ["--db", str(missing), *args])
        assert res.exit_code == 1, (args, res.output)
        assert f"create one with `ottag-db import --db {missing}`" in res.stderr
        assert len(res.stderr.splitlines()) == 1
        assert not missing.exists()
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(cli, ["stats"], env={"OTTAG_DB": None})
    assert res.exit_code == 1 and not (tmp_path / "ottag.sqlite").exists()


def test_id_inputs_and_numbers(runner: CliRunner, bdb: Path, tmp_path: Path) -> None:
    base = json.loads(runner.invoke(cli, ["id", "--db", str(bdb), "--json", "0,0 4,0 1,3 3,3"]).stdout)
    # Negative numbers need no "--", as an argument, from --points, a file or stdin.
    shifted = "-5,-5 -1,-5 -4,-2 -2,-2"
    (tmp_path / "pts.txt").write_text(shifted + "\n")
    for args, stdin in (
        ([shifted], None),
        (shifted.split(), None),
        (["--points", shifted], None),
        (["--file", str(tmp_path / "pts.txt")], None),
        (["-"], shifted),
    ):
        res = runner.invoke(cli, ["id", "--db", str(bdb), "--json", *args], input=stdin)
        assert res.exit_code == 0, (args, res.output)
        got = json.loads(res.stdout)
        assert (got["lambda"], got["id"], got["mp"]) == (base["lambda"], base["id"], base["mp"])
    # Scale-free: tiny and huge coordinates give the same ID, MP in the input's units, no warning.
    for scale in (1e-300, 1e300):
        pts = " ".join(f"{x * scale},{y * scale}" for x, y in ((0, 0), (4, 0), (1, 3), (3, 3)))
        res = runner.invoke(cli, ["id", "--db", str(bdb), "--json", pts])
        assert res.exit_code == 0 and res.stderr == "", res.output
        got = json.loads(res.stdout)
        assert got["lambda"] == base["lambda"] and got["mp"] == pytest.approx(base["mp"] * scale, rel=1e-9)
    res = runner.invoke(cli, ["id", "--db", str(bdb), "0,0 1e-300,0 0,1e-300"])
    assert res.exit_code == 0 and "lambda      3:" in res.stdout
    for pts, code, message in (
        ("nan,0 1,1 0,1", 2, "point 0 (nan,0): coordinates must be finite numbers"),
        ("0,0 inf,1 0,1", 2, "point 1 (inf,1): coordinates must be finite numbers"),
        ("0,0 1e400,1 0,1", 2, "coordinates must be finite numbers"),
        ("-1e308,0 1e308,0 0,1", 2, "too far apart"),
        ("0,0 1e-300,1e-300 2e-300,2e-300", 1, "points 0, 1 and 2 are collinear: 0,0 1e-300,1e-300 2e-300,2e-300"),
    ):
        res = runner.invoke(cli, ["id", "--db", str(bdb), pts])
        assert res.exit_code == code, (pts, res.output)
        assert res.stderr.startswith("error: ") and message in res.stderr and len(res.stderr.splitlines()) == 1
    res = runner.invoke(cli, ["id", "--db", str(bdb), "0,0 1,0 0,1", "--points", "0,0 1,0 0,1"])
    assert res.exit_code == 2 and "give the points once" in res.stderr


def test_id_without_a_database_still_identifies(
    runner: CliRunner, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(cli, ["id", "--json", "0,0 4,0 1,3"], env={"OTTAG_DB": None})
    assert res.exit_code == 0 and json.loads(res.stdout)["in_database"] is False
    assert "the ID is not looked up" in res.stderr and not (tmp_path / "ottag.sqlite").exists()


def test_point_file_checks(runner: CliRunner, bdb: Path, tmp_path: Path) -> None:
    official = tmp_path / "otypes07.b08"
    official.write_bytes(_bundled(7).read_bytes())
    _assert_fails_unchanged(
        runner, bdb, ["--points", "5", str(official)], 2, "the name says 7 points per record, which is authoritative"
    )
    renamed = tmp_path / "seven.b08"
    renamed.write_bytes(_bundled(7).read_bytes())
    fresh = tmp_path / "fresh.sqlite"
    assert runner.invoke(cli, ["import", "--db", str(fresh), "-q", str(_bundled(5))]).exit_code == 0
    for n in ("5", "9"):
        _assert_fails_unchanged(runner, fresh, ["--points", n, str(renamed)], 1, "is --points right?")
    # The same bytes already imported with another n: refused, naming the source to remove.
    _assert_fails_unchanged(runner, bdb, ["--points", "5", str(renamed)], 1, "imported as 7-point records")
    png = tmp_path / "photo.b08"
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(200))
    _assert_fails_unchanged(runner, bdb, ["--points", "5", str(png)], 1, "not a point-set file (its content is a PNG")
    twice = tmp_path / "twice.b08"
    twice.write_bytes(_bundled(6).read_bytes() * 2)
    _assert_fails_unchanged(runner, bdb, ["--points", "6", str(twice)], 1, "records 0 and 16 have the same order type")
    res = runner.invoke(cli, ["import", "--db", str(bdb), "-q", "--points", "6", "--allow-duplicates", str(twice)])
    assert res.exit_code == 0 and "32 records read, 0 new order types, 32 new realizations" in res.stdout


def test_db_check_and_server_urls(runner: CliRunner, bdb: Path) -> None:
    res = runner.invoke(cli, ["db", "check", "--db", str(bdb)])
    assert res.exit_code == 0 and res.stdout == f"{bdb}: ok\n"
    res = runner.invoke(cli, ["stats", "--db", "postgresql://u:pw@localhost/ottag"])
    assert res.exit_code == 1 and "only SQLite databases are supported (got postgresql)" in res.stderr
    assert "pw" not in res.stderr


def test_export_refuses_non_pdf_names_before_opening_the_database(runner: CliRunner, bdb: Path, tmp_path: Path) -> None:
    before = dump_database(bdb)
    for db in (bdb, tmp_path / "missing.sqlite"):
        res = runner.invoke(cli, ["export", "--db", str(db), "--k", "5", str(tmp_path / "x.png")])
        assert res.exit_code == 2, res.output
        assert res.stderr.strip().splitlines() == [
            f"error: {tmp_path / 'x.png'}: export writes a PDF tag sheet, name it .pdf; "
            "for one tag as an image use ottag-db render ID OUT.png|OUT.svg"
        ]
        assert res.stdout == "" and not (tmp_path / "x.png").exists()
    assert not (tmp_path / "missing.sqlite").exists()
    assert dump_database(bdb) == before


def test_four_point_tags_are_explained_in_every_drawing_command(runner: CliRunner, bdb: Path, tmp_path: Path) -> None:
    why = "order types of 4 points cannot be drawn as tags"
    k4 = "4:0210001211012010"
    cases = [
        (["export", "--k", "4", str(tmp_path / "k4.pdf")], 1),
        (["export", "--ids", k4, str(tmp_path / "k4.pdf")], 1),
        (["render", k4, str(tmp_path / "k4.png")], 1),
        (["board", "create", "--k", "4", "--rows", "1", "--cols", "2", str(tmp_path / "b.pdf")], 2),
    ]
    for args, code in cases:
        res = runner.invoke(cli, [*args, "--db", str(bdb)])
        assert res.exit_code == code, (args, res.output)
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and why in lines[0] and "no shared edge" in lines[0], (args, res.stderr)
        assert "Traceback" not in res.output
    assert not list(tmp_path.glob("k4.*")) and not (tmp_path / "b.pdf").exists()
    # Mixed with drawable k: the others are written and k = 4 is said to be skipped.
    res = runner.invoke(cli, ["export", "--db", str(bdb), "--k", "4", "--k", "5", str(tmp_path / "k45.pdf")])
    assert res.exit_code == 0, res.output
    assert res.stdout.startswith(f"{tmp_path / 'k45.pdf'}: 3 tags on 1 page(s)")
    assert f"note: k = 4 skipped: {why}" in res.stderr


def test_export_progress_bar_and_wall_time(runner: CliRunner, bdb: Path, tmp_path: Path) -> None:
    import re
    import time

    out = tmp_path / "t.pdf"
    args = ["export", "--db", str(bdb), "--k", "7", str(out)]
    started = time.perf_counter()
    res = runner.invoke(cli, args)
    elapsed = time.perf_counter() - started
    assert res.exit_code == 0, res.output
    assert "drawing pages" in res.stderr  # the bar (only its label when stderr is no terminal)
    found = re.fullmatch(r".*: 242 tags on (\d+) page\(s\), .*, (\d+\.\d) s\n", res.stdout)
    assert found is not None, res.stdout
    # The whole command (opening the database, selection, drawing, writing), printed to the
    # tenth: not more than the runner measured, and most of it (a loose bound: machines are noisy).
    assert 0.5 * elapsed - 0.05 <= float(found.group(2)) <= elapsed + 0.05, (found.group(2), elapsed)
    quiet = runner.invoke(cli, [*args, "--quiet"])
    assert quiet.exit_code == 0 and quiet.stderr == ""


def test_export_progress_bar_counts_pages_on_a_terminal(bdb: Path, tmp_path: Path) -> None:
    import os
    import pty

    out = tmp_path / "t.pdf"
    primary, secondary = pty.openpty()
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "ottag_db", "export", "--db", str(bdb), "--k", "7", str(out)],
            stderr=secondary,
            stdout=subprocess.PIPE,
            text=True,
            timeout=300,
        )
        os.close(secondary)
        chunks = []
        while True:
            try:
                chunk = os.read(primary, 65536)
            except OSError:
                break
            if not chunk:
                break
            chunks.append(chunk)
    finally:
        os.close(primary)
    assert proc.returncode == 0, proc.stdout
    pages = int(proc.stdout.split(" page(s)")[0].rsplit(" ", 1)[1])
    shown = b"".join(chunks).decode("utf-8", "replace")
    assert "drawing pages" in shown and f"0/{pages}" in shown and f"{pages}/{pages}" in shown
