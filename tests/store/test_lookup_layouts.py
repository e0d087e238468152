"""Decoder lookups carry the printed triangles of each realization (soft decoding checks them)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from ottag_db.core.canonical import canonical_form
from ottag_db.core.layout_check import validate_layout
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary, dictionary_tag_records
from ottag_db.store.lookups import dictionary_lookup, load_lookup
from ottag_db.store.tags import select_tags


def test_layouts_are_the_printed_triangles_in_canonical_labels(bundled_db_path: Path, tmp_path: Path) -> None:
    path = tmp_path / "l.sqlite"
    shutil.copyfile(bundled_db_path, path)
    db = open_database(path)
    try:
        full = load_lookup(db, ks=[6, 7])
        tags = {t.lambda_text: t for t in select_tags(db, ks=[6, 7])}
        create_dictionary(db, "d", DictionaryOptions(ks=(7,), min_flip_distance=2, max_size=6))
        members = dictionary_lookup(db, "d")
        _, records = dictionary_tag_records(db, "d")
    finally:
        db.close()
    for e in full:
        assert len(e.layouts) == len(e.realizations)
        for real, layout in zip(e.realizations, e.layouts, strict=True):
            assert validate_layout(real, layout) == []
            assert canonical_form(real).text == e.lambda_text
    # the best realization's layout is the one export draws, relabeled canonically
    for text, tag in tags.items():
        entry = full.get(text)
        assert entry is not None
        label_of = {file_index: label for label, file_index in enumerate(tag.labeling)}
        drawn = {frozenset(label_of[i] for i in tri) for tri in tag.triangles}
        assert drawn in [{frozenset(t) for t in lay} for lay in entry.layouts]
        assert any(np.array_equal(r, tag.points[list(tag.labeling)]) for r in entry.realizations)
    for rec in records:
        entry = members.get(rec.lambda_text)
        assert entry is not None and len(entry.layouts) == len(entry.realizations) == 1
        label_of = {file_index: label for label, file_index in enumerate(rec.labeling)}
        assert {frozenset(t) for t in entry.layouts[0]} == {
            frozenset(label_of[i] for i in tri) for tri in rec.triangles
        }
