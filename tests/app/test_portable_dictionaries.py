"""Portable dictionaries: a JSON export is the complete definition of a dictionary.

Real SQLite, real PDF (rasterized with pdfium), the real decoder, the CLI as real subprocesses.
A dictionary is exported from a database built from the bundled data and imported into a
database whose realizations of the same order types differ (Aichholzer's reference files when
``OTTAG_AICHHOLZER_DIR`` is set, else the bundled files with every point moved a few grid units
without changing the order type). Its tags, printed from the first database, must decode with
the second database's dictionary and with ``decode --dictionary-file`` alone — though not with
the second database's own realizations. Bad files are refused naming the tag, database unchanged.
"""

from __future__ import annotations

import copy
import itertools
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ottag_db.app.decode_batch import DecodeOptions, DecodeSetup, decode_images, prepare_decoding, prepare_file_decoding
from ottag_db.app.export import TagFilter, export_sheet
from ottag_db.core.canonical import canonical_batch
from ottag_db.core.geometry import general_position_mask
from ottag_db.core.layout_check import validate_layout
from ottag_db.decode import Detector, DetectorParams
from ottag_db.errors import DictionaryError
from ottag_db.files.bundled import bundled_point_files
from ottag_db.files.pointfile import read_point_file, write_point_file
from ottag_db.printing.sheet import SheetOptions
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary, delete_dictionary, get_dictionary
from ottag_db.store.dictionary_files import export_dictionary, import_dictionary, parse_dictionary
from ottag_db.store.importer import import_point_file
from ottag_db.store.lookups import dictionary_lookup, load_lookup
from ottag_db.store.models import Source
from tests.support.database import dump_database
from tests.support.sources import aichholzer_dir

pdfium = pytest.importorskip("pypdfium2")
cv2 = pytest.importorskip("cv2")

ROOT = Path(__file__).resolve().parents[2]
KS = (7, 8)
DPI = 200
NAME = "travel"


def _run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("OTTAG_DB", None)
    return subprocess.run(
        [sys.executable, "-m", "ottag_db", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        check=False,
        cwd=cwd,
    )


def _perturb(points: np.ndarray, seed: int) -> np.ndarray:
    """Every set moved point by point (up to 32 grid units, less where needed) keeping its order type."""
    rng = np.random.default_rng(seed)
    want = canonical_batch(points).texts()
    out = points.copy()
    todo = np.arange(len(points))
    for step in (32, 28, 24, 20, 16, 16, 12, 12, 10, 8, 8, 6, 6, 4, 4, 3, 3, 2, 2):
        if todo.size == 0:
            break
        cand = np.clip(points[todo] + rng.integers(-step, step + 1, size=points[todo].shape), 0, 255)
        ok = general_position_mask(cand)
        texts = canonical_batch(cand[ok]).texts() if ok.any() else []
        same = np.zeros(len(todo), dtype=bool)
        same[np.flatnonzero(ok)] = [t == want[i] for t, i in zip(texts, todo[ok], strict=True)]
        out[todo[same]] = cand[same]
        todo = todo[~same]
    return out


@pytest.fixture(scope="module")
def first_db(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the bundled database with dictionary ``travel`` (k = 7, 8; both polarities)."""
    path = tmp_path_factory.mktemp("first") / "first.sqlite"
    shutil.copyfile(bundled_db_path, path)
    with open_database(path) as db:
        create_dictionary(db, NAME, DictionaryOptions(ks=KS, polarity="both", max_size=24))
    return path


@pytest.fixture(scope="module")
def exported(first_db: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("json") / "travel.json"
    result = _run("dictionary", "export", NAME, "--output", str(out), "--quiet", "--db", str(first_db))
    assert result.returncode == 0, result.stderr
    return out


@pytest.fixture(scope="module")
def second_db(tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest) -> Path:
    """A database of the same order types with other realizations (no dictionary yet)."""
    folder = tmp_path_factory.mktemp("second")
    path = folder / "second.sqlite"
    if aichholzer_dir() is not None:
        shutil.copyfile(request.getfixturevalue("mirrors_db_path"), path)
        return path
    with open_database(path) as db:
        for file, k in bundled_point_files():
            if k in KS:
                moved = folder / f"moved{k:02d}.b08"
                write_point_file(moved, _perturb(read_point_file(file), seed=k))
                import_point_file(db, moved, n=k, with_mirrors=True)
    return path


@pytest.fixture(scope="module")
def pages(first_db: Path, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """The dictionary's tags printed from the first database: PDF pages rasterized as PNG."""
    folder = tmp_path_factory.mktemp("pages")
    pdf = folder / "travel.pdf"
    with open_database(first_db) as db:
        export_sheet(db, pdf, TagFilter(), SheetOptions(), dictionary=NAME)
    return _rasterize(pdf, folder)


def _rasterize(pdf: Path, folder: Path) -> list[Path]:
    """The pages of ``pdf`` as grey PNG files at :data:`DPI`."""
    doc = pdfium.PdfDocument(str(pdf))
    out = []
    try:
        for i in range(len(doc)):
            page = doc[i]
            img = page.render(scale=DPI / 72.0, grayscale=True).to_numpy()
            page.close()
            png = folder / f"page{i}.png"
            assert cv2.imwrite(str(png), img if img.ndim == 2 else img[:, :, 0])
            out.append(png)
    finally:
        doc.close()
    return out


@pytest.fixture(scope="module")
def imported_db(second_db: Path, exported: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("imported") / "second.sqlite"
    shutil.copyfile(second_db, path)
    result = _run("dictionary", "import", str(exported), "--quiet", "--db", str(path))
    assert result.returncode == 0, result.stderr
    assert f"imported dictionary {NAME}: 24 tags" in result.stdout
    return path


def _decoded(setup: DecodeSetup, pages: list[Path]) -> list[dict[str, Any]]:
    records = list(decode_images(setup, pages, DecodeOptions()))
    assert all("error" not in r for r in records)
    return [d for r in records for d in r["detections"]]


def _check_every_tag(detections: list[dict[str, Any]], tags: list[dict[str, Any]]) -> None:
    by_number = {t["number"]: t for t in tags}
    got = sorted(d["tag"] for d in detections)
    assert got == sorted(by_number), f"decoded tags {got}"
    for d in detections:
        t = by_number[d["tag"]]
        assert (d["lambda"], d["polarity"]) == (t["lambda"], t["polarity"])
        assert d["number"] == t["universal_number"]


def test_realizations_differ_between_the_databases(second_db: Path, exported: Path) -> None:
    tags = json.loads(exported.read_text())["tags"]
    with open_database(second_db) as db:
        own = load_lookup(db, ks=KS)
    for t in tags:
        entry = own.get(t["lambda"])
        assert entry is not None  # the order type is there …
        pts = np.array(t["points"], dtype=np.float64)
        # … but no realization of it is the exported one (in any labeling)
        assert all(sorted(map(tuple, r.tolist())) != sorted(map(tuple, pts.tolist())) for r in entry.realizations)


def test_printed_tags_decode_with_the_imported_dictionary_and_the_file_alone(
    second_db: Path, imported_db: Path, exported: Path, pages: list[Path], capsys: pytest.CaptureFixture[str]
) -> None:
    tags = json.loads(exported.read_text())["tags"]
    assert len(tags) == 24 and {t["k"] for t in tags} <= set(KS)
    # Control: the second database's own realizations do not verify the printed tags.
    with open_database(second_db) as db:
        own = Detector(load_lookup(db, ks=KS), DetectorParams())
    control = [d for p in pages for d in own.detect(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE))]
    with open_database(imported_db) as db:
        via_db = _decoded(prepare_decoding(db, NAME), pages)
        lookup = dictionary_lookup(db, NAME)
    via_file = _decoded(prepare_file_decoding(exported), pages)
    with capsys.disabled():
        print(
            f"\nportable dictionary: {len(tags)} tags printed from database 1; decoded with database 2's own "
            f"realizations {len(control)}, with its imported dictionary {len(via_db)}, with the file alone "
            f"{len(via_file)}"
        )
    assert len(control) < len(tags) // 2
    _check_every_tag(via_db, tags)
    _check_every_tag(via_file, tags)
    # The imported dictionary verifies against exactly the file's geometry.
    doc = parse_dictionary(exported.read_text())
    for t in doc.tags:
        entry = lookup.get(t.lambda_text)
        assert entry is not None and any(np.array_equal(r, t.canonical_points()) for r in entry.realizations)
        assert len(entry.realizations) <= 2  # normal and inverted members share one geometry here
    # Re-exporting from the second database gives the same tags back.
    with open_database(imported_db) as db:
        again = json.loads(export_dictionary(db, NAME))["tags"]
    keys = ("number", "lambda", "polarity", "points", "triangles")
    assert [{k: t[k] for k in keys} for t in again] == [{k: t[k] for k in keys} for t in tags]


def test_cli_decodes_with_the_dictionary_file_alone(exported: Path, pages: list[Path], tmp_path: Path) -> None:
    tags = json.loads(exported.read_text())["tags"]
    result = _run("decode", "--dictionary-file", str(exported), "--json", "--quiet", *map(str, pages), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    dets = [d for line in result.stdout.splitlines() for d in json.loads(line)["detections"]]
    _check_every_tag(dets, tags)
    assert list(tmp_path.iterdir()) == []  # no database was opened or created
    both = _run("decode", "--dictionary", NAME, "--dictionary-file", str(exported), str(pages[0]))
    assert both.returncode == 2 and "exclude each other" in both.stderr


def test_printing_from_the_second_database_uses_the_imported_geometry(imported_db: Path, exported: Path) -> None:
    tags = json.loads(exported.read_text())["tags"]
    with open_database(imported_db) as db:
        info = get_dictionary(db, NAME)
        assert [(m.number, m.points, m.triangles) for m in info.members] == [
            (t["number"], t["points"], t["triangles"]) for t in tags
        ]
        for m in info.members:
            assert validate_layout(np.array(m.points), m.triangles) == []


def test_a_sheet_printed_from_the_second_database_decodes_there(imported_db: Path, tmp_path: Path) -> None:
    """Needs ``export --dictionary`` to print each member's own realization
    (:func:`ottag_db.store.dictionaries.dictionary_tag_records`); while app/export.py prints the
    order type's best realization this holds only because the imported geometry has the
    highest MP here."""
    pdf = tmp_path / "second.pdf"
    with open_database(imported_db) as db:
        export_sheet(db, pdf, TagFilter(), SheetOptions(), dictionary=NAME)
        tags = json.loads(export_dictionary(db, NAME))["tags"]
        _check_every_tag(_decoded(prepare_decoding(db, NAME), _rasterize(pdf, tmp_path)), tags)


def test_delete_removes_the_imported_geometry(imported_db: Path, tmp_path: Path) -> None:
    path = tmp_path / "d.sqlite"
    shutil.copyfile(imported_db, path)
    with open_database(path) as db:
        with db.session() as s:
            assert s.query(Source).filter(Source.file_name == f"dictionary:{NAME}").count() == 1
        assert delete_dictionary(db, NAME) == 24
        with db.session() as s:
            assert s.query(Source).filter(Source.file_name == f"dictionary:{NAME}").count() == 0


# ---------------------------------------------------------------- refusals


def _collinear(data: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    tag = data["tags"][3]
    pts = [[2 * x, 2 * y] for x, y in tag["points"]]  # doubled: the midpoint is on the grid
    pts[2] = [(pts[0][0] + pts[1][0]) // 2, (pts[0][1] + pts[1][1]) // 2]
    tag["points"] = pts
    return data, tag


def _wrong_lambda(data: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    tag = data["tags"][4]
    other = next(t for t in data["tags"] if t["k"] == tag["k"] and t["lambda"] != tag["lambda"])
    tag["lambda"] = other["lambda"]
    return data, tag


def _overlapping(data: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    tag = data["tags"][5]
    pts = np.array(tag["points"])
    k = len(pts)
    found: list[tuple[int, list[list[int]]]] = []
    for pair in itertools.combinations(itertools.combinations(range(k), 3), 2):
        rest = [i for i in range(k) if i not in set(pair[0]) | set(pair[1])]
        tris = [list(t) for t in pair] + [rest[i : i + 3] for i in range(0, len(rest) - 2, 3)]
        problems = validate_layout(pts, tris)
        if len({i for t in tris for i in t}) == k and any("overlap" in e for e in problems[:3]):
            found.append((len(problems), tris))
    assert found
    tag["triangles"] = min(found)[1]  # the layout breaking the fewest rules, overlap among them
    return data, tag


@pytest.mark.parametrize(
    ("make", "problem"),
    [
        (_collinear, "collinear"),
        (_wrong_lambda, "the points are order type"),
        (_overlapping, "overlap"),
    ],
)
def test_bad_files_are_refused_naming_the_tag(
    make: Any, problem: str, exported: Path, second_db: Path, tmp_path: Path
) -> None:
    data, tag = make(copy.deepcopy(json.loads(exported.read_text())))
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    db = tmp_path / "db.sqlite"
    shutil.copyfile(second_db, db)
    before = dump_database(db)
    for args in (
        ("dictionary", "import", str(bad), "--db", str(db)),
        ("decode", "--dictionary-file", str(bad), "x.png"),
    ):
        result = _run(*args)
        assert result.returncode == 1, result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
        assert f"tag {tag['number']} (λ {tag['lambda']})" in lines[0] and problem in lines[0], lines[0]
    assert dump_database(db) == before
    with pytest.raises(DictionaryError, match=problem), open_database(db) as d:
        import_dictionary(d, bad.read_text(), source=str(bad))
    assert dump_database(db) == before


def test_malformed_entries_are_refused(exported: Path) -> None:
    data = json.loads(exported.read_text())
    cases = {
        "points": ([[1.5, 2]] * 7, "integer grid coordinates"),
        "triangles": ([[0, 1]], "point indices"),
        "polarity": ("sideways", "polarity must be"),
        "lambda": ("5:0", "not an order-type ID"),
    }
    for key, (value, message) in cases.items():
        broken = copy.deepcopy(data)
        broken["tags"][0][key] = value
        with pytest.raises(DictionaryError, match=message):
            parse_dictionary(json.dumps(broken), source="f.json")
    twice = copy.deepcopy(data)
    twice["tags"][1]["number"] = twice["tags"][0]["number"]
    with pytest.raises(DictionaryError, match="appears twice"):
        parse_dictionary(json.dumps(twice))
    other = copy.deepcopy(data)
    other["format"] = "ottag-dictionary/9"
    with pytest.raises(DictionaryError, match="format"):
        parse_dictionary(json.dumps(other))
