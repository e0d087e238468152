"""Soft decoding end to end: a tag read one flip away from a D = 3 dictionary member is corrected,
and refused (not misread) when the flipped candidates are ambiguous (real SQLite, real OpenCV)."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ottag_db.app.decoding import detection_json
from ottag_db.core.canonical import canonical_form
from ottag_db.core.geometry import orientation_tensor
from ottag_db.core.layout_check import validate_layout
from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.core.single_set import orientation_table
from ottag_db.decode import Detector, DetectorParams
from ottag_db.printing import scenes
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary, dictionary_tag_records
from ottag_db.store.lookups import dictionary_lookup

#: Distance (grid units) of the moved point from the line on either side: 1 grid unit is about
#: 0.35 px in the image below, well under the 1 px margin the decoder trusts.
WEAK = 1.0
#: Data-area side in the image (px).
SIDE = 115.0


def _signs(pts: np.ndarray) -> np.ndarray:
    return np.sign(orientation_tensor(pts)[0])


def _weak_pair(tag: scenes.DrawableTag) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int]]:
    """The tag's points with one point moved to ``WEAK`` grid units from the line of two others:
    on its own side (the same order type) and across (a flip neighbour), both drawable."""
    pts = tag.points
    table = orientation_table(pts)
    first, second = table.pairs.first, table.pairs.second
    rows, cols = np.unravel_index(np.argsort(table.distance, axis=None), table.distance.shape)
    for r, p in zip(rows.tolist(), cols.tolist(), strict=True):
        a, b = int(first[r]), int(second[r])
        if p in (a, b) or not np.isfinite(table.distance[r, p]):
            continue
        d = pts[b] - pts[a]
        nrm = np.array([-d[1], d[0]]) / np.hypot(d[0], d[1])
        s = float(nrm @ (pts[p] - pts[a]))
        same, across = pts.copy(), pts.copy()
        same[p] += (np.sign(s) * WEAK - s) * nrm
        across[p] += (-np.sign(s) * WEAK - s) * nrm
        if (same < 0).any() or (same > 255).any() or (across < 0).any() or (across > 255).any():
            continue
        if not np.array_equal(_signs(same), _signs(pts)):
            continue
        if np.count_nonzero(_signs(across) != _signs(pts)) != 6:  # one triple, its 6 permutations
            continue
        if validate_layout(same, tag.triangles) or validate_layout(across, tag.triangles):
            continue
        return same, across, tuple(sorted((a, b, p)))  # type: ignore[return-value]
    raise AssertionError("no point of the member can be moved next to a line")


@pytest.fixture(scope="module")
def d3(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[MemoryLookup, scenes.DrawableTag, int]:
    """The D = 3 dictionary of 7-point tags: its lookup, its first member's tag and number."""
    path = tmp_path_factory.mktemp("soft") / "d3.sqlite"
    shutil.copyfile(bundled_db_path, path)
    db = open_database(path)
    try:
        info = create_dictionary(db, "d3", DictionaryOptions(ks=(7,), min_flip_distance=3))
        assert info.min_flip_distance == 3 and len(info.members) > 1
        lookup = dictionary_lookup(db, "d3")
        _, records = dictionary_tag_records(db, "d3")
    finally:
        db.close()
    rec = records[0]
    tag = scenes.drawable_from_file_order(
        rec.lambda_text, rec.points, rec.labeling, rec.triangles, rec.placement, rec.printed_mp_unit
    )
    assert rec.tag is not None
    return lookup, tag, rec.tag


def _scene(tag: scenes.DrawableTag, points: np.ndarray) -> np.ndarray:
    """The tag drawn with ``points``, data area ``SIDE`` px, a mild perspective, no noise."""
    hom = np.array([[SIDE, 0.08 * SIDE, 60.0], [-0.05 * SIDE, 0.95 * SIDE, 50.0], [2e-4 * SIDE, 1e-4 * SIDE, 1.0]])
    spec = scenes.TagSpec(points, tag.triangles, hom, "normal", placement=tag.placement)
    return scenes.render_scene((260, 260), [spec], np.random.default_rng(0), blur=0.4).image


def test_a_flipped_weak_triple_is_corrected_against_a_d3_dictionary_and_refused_when_ambiguous(
    d3: tuple[MemoryLookup, scenes.DrawableTag, int],
) -> None:
    lookup, tag, number = d3
    same, across, _triple = _weak_pair(tag)
    member = lookup.get(tag.lambda_text)
    assert member is not None and member.layouts
    # the member is verified against its weak geometry; the tag in the image has the point across
    weak = MemoryLookup(replace(e, realizations=(same,)) if e is member else e for e in lookup)
    img = _scene(tag, across)
    neighbour = canonical_form(across)
    assert lookup.get(neighbour.text) is None  # one flip from a member: not in a D = 3 dictionary

    off, rejected = Detector(weak, DetectorParams(soft_max_flips=0)).detect_with_rejections(img)
    low = [r for r in rejected if r.lambda_text is not None]
    assert off == [] and [(r.reason, r.lambda_text) for r in low] == [("low_margin", neighbour.text)]

    dets = Detector(weak).detect(img)
    assert len(dets) == 1
    det = dets[0]
    assert (det.lambda_text, det.tag, det.corrected_flips) == (tag.lambda_text, number, 1)
    assert det.margin_px < 1.0
    out = json.loads(json.dumps(detection_json(det)))
    assert out["corrected_flips"] == 1 and out["lambda"] == tag.lambda_text

    # the neighbour printed as drawn is also a tag: two candidates verify, the reading is refused
    lab = list(neighbour.labeling)
    label_of = {point: label for label, point in enumerate(lab)}
    other = LookupEntry(
        neighbour.text, tag.k, -1, neighbour.unique_min, (across[lab],), 999, {"tags": {"normal": 999}},
        (tuple((label_of[a], label_of[b], label_of[c]) for a, b, c in tag.triangles),),
    )  # fmt: skip
    both = MemoryLookup([*weak, other])
    dets, rejected = Detector(both).detect_with_rejections(img)
    assert dets == []
    low = [r for r in rejected if r.lambda_text is not None]
    assert [r.reason for r in low] == ["low_margin"] and "2 of 2 candidates verify" in low[0].detail
