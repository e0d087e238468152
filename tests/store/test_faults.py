"""Fault suite: real SQLite files, real subprocesses (``python -m ottag_db``), real signals.

Corrupt pages, a read-only file and folder, a locked database, SIGKILL/SIGINT/SIGTERM during
a large import, two processes importing into a new database at once. Each case checks the
one-line message, the exit code, and that ``PRAGMA integrity_check`` is ok with the row
counts unchanged or complete.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from ottag_db.core.geometry import general_position_mask
from ottag_db.files.bundled import bundled_point_files
from ottag_db.files.pointfile import write_point_file
from ottag_db.store.db import open_database
from ottag_db.store.importer import import_point_file

TABLES = ("sources", "order_types", "realizations", "layouts")


def _bundled(k: int) -> Path:
    return next(p for p, kk in bundled_point_files() if kk == k)


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "OTTAG_DB"}
    env.update(extra)
    return env


def _run(*args: str, timeout_s: str | None = None) -> subprocess.CompletedProcess[str]:
    env = _env(OTTAG_DB_TIMEOUT=timeout_s) if timeout_s else _env()
    return subprocess.run(
        [sys.executable, "-m", "ottag_db", *args], capture_output=True, text=True, env=env, timeout=120, check=False
    )


def _start(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "ottag_db", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
    )


def _counts(path: Path) -> dict[str, int]:
    con = sqlite3.connect(path)
    try:
        return {t: int(con.execute(f"SELECT count(*) FROM {t}").fetchone()[0]) for t in TABLES}
    finally:
        con.close()


def _integrity(path: Path) -> str:
    con = sqlite3.connect(path)
    try:
        return str(con.execute("PRAGMA integrity_check").fetchone()[0])
    finally:
        con.close()


def _one_error_line(res: subprocess.CompletedProcess[str], *needles: str) -> str:
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert "Traceback" not in res.stderr, res.stderr
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 1, res.stderr
    for needle in needles:
        assert needle in errors[0], errors[0]
    return errors[0]


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def small_db(tmp_path: Path) -> Path:
    """A database with the bundled 5- and 6-point files (mirrors included)."""
    path = tmp_path / "small.sqlite"
    db = open_database(path)
    try:
        for k in (5, 6):
            import_point_file(db, _bundled(k), with_mirrors=True)
    finally:
        db.close()
    return path


@pytest.fixture(scope="module")
def medium_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A database with the bundled 5-, 6- and 7-point files (mirrors included). Copy before use."""
    path = tmp_path_factory.mktemp("medium") / "medium.sqlite"
    db = open_database(path)
    try:
        for k in (5, 6, 7):
            import_point_file(db, _bundled(k), with_mirrors=True)
    finally:
        db.close()
    return path


@pytest.fixture(scope="module")
def big_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """2000 random 8-point sets on the 16-bit grid, in general position: seconds to import."""
    rng = np.random.default_rng(11)
    pts = rng.integers(0, 65536, size=(2400, 8, 2))
    pts = pts[general_position_mask(pts)][:2000]
    assert pts.shape[0] == 2000
    path = tmp_path_factory.mktemp("big") / "big.b16"
    write_point_file(path, pts)
    return path


def _corrupt(src: Path, dest: Path, every: int) -> None:
    """Copy ``src`` (checkpointed) and overwrite every ``every``-th page after page 1 with junk."""
    shutil.copyfile(src, dest)
    con = sqlite3.connect(dest)
    con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    page, count = con.execute("PRAGMA page_size").fetchone()[0], con.execute("PRAGMA page_count").fetchone()[0]
    con.close()
    with dest.open("r+b") as fh:
        for i in range(1, count, every):
            fh.seek(i * page)
            fh.write(b"\xa5" * page)
    assert dest.read_bytes()[:16] == b"SQLite format 3\x00"


@pytest.mark.parametrize("every", [1, 5])
def test_corrupt_pages_give_one_line_in_every_command(
    medium_db: Path, tmp_path: Path, every: int, big_file: Path
) -> None:
    bad = tmp_path / "bad.sqlite"
    _corrupt(medium_db, bad, every)
    before = _sha(bad)
    image = tmp_path / "scene.png"
    image.write_bytes(b"")
    import cv2

    cv2.imwrite(str(image), np.full((64, 64), 255, np.uint8))
    commands = [
        ["stats"],
        ["list", "--format", "json"],
        ["export", "--k", "7", str(tmp_path / "t.pdf")],
        ["import", "--points", "8", "--allow-duplicates", str(big_file)],
    ]
    if every == 1:  # every table damaged: also the commands that read little
        commands += [
            ["show", "5"],
            ["render", "5", str(tmp_path / "t.png")],
            ["db", "check"],
            ["decode", str(image)],
            ["dictionary", "list"],
            ["sources"],
            ["id", "0,0", "4,0", "0,4"],
        ]
    for cmd in commands:
        res = _run("--db", str(bad), *cmd)
        assert res.returncode == 1, (cmd, res.stderr)
        _one_error_line(res, str(bad), "corrupt", "backup")
    assert _sha(bad) == before


def test_db_check_reports_ok_and_damage(small_db: Path, medium_db: Path, tmp_path: Path) -> None:
    res = _run("db", "check", "--db", str(small_db))
    assert res.returncode == 0 and res.stdout.strip() == f"{small_db}: ok"
    bad = tmp_path / "bad.sqlite"
    _corrupt(medium_db, bad, 9)
    res = _run("db", "check", "--db", str(bad))
    assert res.returncode == 1
    _one_error_line(res, str(bad))


def _can_make_read_only() -> bool:
    return os.geteuid() != 0 or shutil.which("chattr") is not None


@pytest.fixture
def read_only() -> Iterator[list[Path]]:
    """Paths appended here are made read-only (chmod, or ``chattr +i`` for root) and restored after."""
    paths: list[Path] = []

    yield paths
    for p in paths:
        if os.geteuid() == 0:
            subprocess.run(["chattr", "-i", str(p)], check=False)
        p.chmod(0o755 if p.is_dir() else 0o644)


def _make_read_only(p: Path, registry: list[Path]) -> None:
    registry.append(p)
    if os.geteuid() == 0:
        if subprocess.run(["chattr", "+i", str(p)], check=False, capture_output=True).returncode:
            pytest.skip("running as root and chattr +i is not permitted here")
    else:
        p.chmod(0o555 if p.is_dir() else 0o444)


@pytest.mark.skipif(not _can_make_read_only(), reason="root without chattr cannot make a file read-only")
def test_read_only_file_and_folder(small_db: Path, tmp_path: Path, read_only: list[Path]) -> None:
    before = _counts(small_db)
    folder = tmp_path / "ro"
    folder.mkdir()
    in_folder = folder / "db.sqlite"
    shutil.copyfile(small_db, in_folder)
    _make_read_only(small_db, read_only)
    res = _run("import", "--db", str(small_db), str(_bundled(7)))
    assert res.returncode == 1
    _one_error_line(res, str(small_db), "cannot write", "permission")
    res = _run("dictionary", "create", "d", "--k", "6", "--db", str(small_db))
    assert res.returncode == 1
    _one_error_line(res, str(small_db), "cannot write")
    # Exporting never writes: it works on a read-only file.
    assert _run("export", "--k", "6", "--db", str(small_db), str(tmp_path / "t.pdf")).returncode == 0
    _make_read_only(folder, read_only)
    for cmd in (["import", str(_bundled(7))], ["stats"]):
        res = _run(*cmd, "--db", str(in_folder))
        assert res.returncode == 1
        _one_error_line(res, str(in_folder), "permission", "folder")
    for p in read_only:
        if os.geteuid() == 0:
            subprocess.run(["chattr", "-i", str(p)], check=True)
    for db in (small_db, in_folder):
        assert _integrity(db) == "ok" and _counts(db) == before


def test_locked_database(small_db: Path) -> None:
    before = _counts(small_db)
    holder = sqlite3.connect(small_db, isolation_level=None)
    try:
        holder.execute("BEGIN IMMEDIATE")
        start = time.monotonic()
        res = _run("import", "--db", str(small_db), str(_bundled(7)), timeout_s="1")
        assert res.returncode == 1
        _one_error_line(res, str(small_db), "locked by another process", "OTTAG_DB_TIMEOUT")
        assert time.monotonic() - start < 30
        # Readers are not blocked by a writer (WAL).
        assert _run("stats", "--db", str(small_db), timeout_s="1").returncode == 0
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert _integrity(small_db) == "ok" and _counts(small_db) == before
    assert _run("import", "--db", str(small_db), str(_bundled(7))).returncode == 0


def _wait_for_line(stream: object, text: str) -> None:
    for line in iter(stream.readline, ""):  # type: ignore[attr-defined]
        if text in line:
            return
    raise AssertionError(f"the process ended before printing {text!r}")


def test_sigkill_during_a_large_import(small_db: Path, big_file: Path) -> None:
    before = _counts(small_db)
    outcomes = []
    for delay in (0.3, 1.2, None):
        proc = _start("import", "--points", "8", "--allow-duplicates", "--db", str(small_db), str(big_file))
        if delay is None:  # after the first progress report: in the middle of the transaction
            _wait_for_line(proc.stderr, "importing big.b16")
        else:
            time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
        assert _integrity(small_db) == "ok"
        outcomes.append(_counts(small_db))
        if outcomes[-1] != before:  # finished before the kill: nothing more to interrupt
            break
    if outcomes[-1] == before:
        res = _run("import", "-q", "--points", "8", "--allow-duplicates", "--db", str(small_db), str(big_file))
        assert res.returncode == 0, res.stderr
    complete = _counts(small_db)
    assert complete["realizations"] == before["realizations"] + 2000
    assert complete["sources"] == before["sources"] + 1
    assert all(c in (before, complete) for c in outcomes), outcomes
    assert _integrity(small_db) == "ok"


def test_sigkill_during_first_use_then_import_works(tmp_path: Path) -> None:
    db = tmp_path / "new.sqlite"
    proc = _start("import", "--db", str(db), str(_bundled(7)))
    time.sleep(0.4)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    res = _run("import", "--db", str(db), str(_bundled(7)))
    assert res.returncode == 0, res.stderr
    assert _integrity(db) == "ok" and _counts(db)["order_types"] == 135


@pytest.mark.parametrize(("sig", "code", "name"), [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM")])
def test_interrupt_rolls_back_and_says_so(
    small_db: Path, big_file: Path, sig: signal.Signals, code: int, name: str
) -> None:
    before = _counts(small_db)
    proc = _start("import", "--points", "8", "--allow-duplicates", "--db", str(small_db), str(big_file))
    _wait_for_line(proc.stderr, "importing big.b16")
    proc.send_signal(sig)
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert f"interrupted ({name}): big.b16 not imported, the database is unchanged" in err
    assert "Aborted!" not in err and "Traceback" not in err
    assert _integrity(small_db) == "ok" and _counts(small_db) == before


def test_interrupt_after_a_commit_says_what_was_committed(small_db: Path, big_file: Path, tmp_path: Path) -> None:
    before = _counts(small_db)
    second = tmp_path / "second.b16"
    second.write_bytes(big_file.read_bytes()[32:])  # the records after the first: other content
    proc = _start("import", "--points", "8", "--allow-duplicates", "--db", str(small_db), str(big_file), str(second))
    assert proc.stdout is not None
    _wait_for_line(proc.stdout, "big.b16: 2000 records read")
    proc.send_signal(signal.SIGINT)
    _out, err = proc.communicate(timeout=60)
    assert "Aborted!" not in err and "Traceback" not in err
    after = _counts(small_db)
    assert _integrity(small_db) == "ok"
    if proc.returncode == 130 and after["realizations"] == before["realizations"] + 2000:
        assert "interrupted (SIGINT): second.b16 not imported, the database is unchanged" in err
        assert "files already committed: big.b16" in err
        assert after["sources"] == before["sources"] + 1
    elif proc.returncode == 130:  # the signal landed just after the second file's commit
        assert "second.b16 was imported (committed) before the signal" in err
        assert "files already committed: big.b16, second.b16" in err
        assert after["realizations"] == before["realizations"] + 3999
    else:  # the second file finished before the signal arrived
        assert proc.returncode == 0 and after["realizations"] == before["realizations"] + 3999


def test_two_processes_import_into_a_new_database(tmp_path: Path) -> None:
    db = tmp_path / "new.sqlite"
    six, seven = str(_bundled(6)), str(_bundled(7))
    procs = [_start("import", "-q", "--db", str(db), *files) for files in ((six, seven), (seven, six))]
    outs = [p.communicate(timeout=120) for p in procs]
    for p, (_out, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err
        assert err == ""
    new = 0
    for out, _err in outs:
        for line in out.splitlines():
            if "new order types" in line and not line.startswith("total"):
                new += int(line.split(" records read, ")[1].split(" new order types")[0])
    counts = _counts(db)
    assert counts["sources"] == 2 and counts["order_types"] == 151 == new
    assert _integrity(db) == "ok"
