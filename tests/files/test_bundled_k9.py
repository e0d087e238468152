"""The shipped nine-point file: its manifest entry, its order types, and ``import --k 9``.

The module skips when ``data/ottag-k09.b08`` is not there (a checkout that removed it: the
default import does not need it).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ottag_db.cli import cli
from ottag_db.core.canonical import canonical_batch, canonicalize_lambdas, mirror_lambdas
from ottag_db.core.geometry import lambda_matrices, maximal_perturbations
from ottag_db.core.types import COMPLETE_COUNTS, MP_THRESHOLDS
from ottag_db.files.bundled import bundled_files_available, bundled_manifest, bundled_point_files
from ottag_db.files.pointfile import OFFICIAL_RECORD_COUNTS, file_sha256, read_point_file
from ottag_db.files.resources import data_dir

#: Nine-point order types with a unique minimal λ-matrix (E^9), both chiralities and up to
#: reflection (benchmarks/unique_min_counts.py; the import computes them independently).
E9 = 316_756
E9_UP_TO_REFLECTION = 158_787
_CHUNK = 20_000

if not (data_dir() / "ottag-k09.b08").exists():
    pytest.skip("data/ottag-k09.b08 is not in this checkout (README, 'Nine points')", allow_module_level=True)


@pytest.fixture(scope="module")
def nine() -> np.ndarray:
    return read_point_file(data_dir() / "ottag-k09.b08", 9)


def test_manifest_entry_and_bytes(nine: np.ndarray) -> None:
    manifest = bundled_manifest()
    entry = manifest["files"]["9"]
    assert entry["file"] == "ottag-k09.b08" and entry["points"] == 9
    assert entry["default"] is False  # imported on request: `import --k 9`
    assert entry["records"] == OFFICIAL_RECORD_COUNTS[9] == nine.shape[0]
    assert entry["order_types_with_mirrors"] == COMPLETE_COUNTS[9]
    assert entry["sha256"] == file_sha256(data_dir() / "ottag-k09.b08")
    mp = maximal_perturbations(nine)
    assert manifest["mp_summary"]["counts_at_least"]["9"] == [int((mp >= v).sum()) for v in MP_THRESHOLDS]
    assert entry["mp_min"] == round(float(mp.min()), 6)
    assert [k for _p, k in bundled_point_files()] == [3, 4, 5, 6, 7, 8]
    assert [(k, default) for _p, k, default in bundled_files_available() if k == 9] == [(9, False)]


@pytest.mark.slow
def test_every_nine_point_order_type_once_sorted(nine: np.ndarray) -> None:
    # One record per reflection pair, the chirality with the smaller ID, sorted by that ID:
    # with the mirrors that is every one of the 316,809 order types of nine points.
    texts: list[str] = []
    mirrors: list[str] = []
    for start in range(0, nine.shape[0], _CHUNK):
        lam = lambda_matrices(nine[start : start + _CHUNK])
        texts += canonicalize_lambdas(lam).texts()
        mirrors += canonicalize_lambdas(mirror_lambdas(lam)).texts()
    assert texts == sorted(texts) and len(set(texts)) == len(texts)
    assert all(t <= m for t, m in zip(texts, mirrors, strict=True))
    assert len(set(texts) | set(mirrors)) == COMPLETE_COUNTS[9]
    assert canonical_batch(nine[:5].astype(np.float64)).texts() == texts[:5]


@pytest.mark.slow
def test_import_k9_and_stats(runner: CliRunner, tmp_path: Path) -> None:
    db = str(tmp_path / "nine.sqlite")
    res = runner.invoke(cli, ["import", "--db", db, "--quiet", "--k", "9", "--jobs", "2"])
    assert res.exit_code == 0, res.output
    assert res.stdout.startswith("ottag-k09.b08: 158817 records read, 316809 new order types")
    stats = json.loads(runner.invoke(cli, ["stats", "--db", db, "--json"]).stdout)
    nine = stats["9"]
    assert nine["complete"] is True and nine["order_types"] == COMPLETE_COUNTS[9]
    assert nine["unique_min"] == E9
    assert nine["up_to_reflection"]["order_types"] == OFFICIAL_RECORD_COUNTS[9]
    assert nine["up_to_reflection"]["unique_min"] == E9_UP_TO_REFLECTION
    counts = bundled_manifest()["mp_summary"]["counts_at_least"]["9"]
    assert list(nine["up_to_reflection"]["mp_at_least"].values()) == counts
