"""Identification stage: points → ID → lookup entry (→ verification)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import DetectorParams
from ottag_db.decode.identify import Catalogue, identify
from ottag_db.decode.profile import StageClock
from ottag_db.decode.types import Detection, Quad, Rejection
from tests.support import synthetic_tags as syn

SIDE, ORIGIN = 200.0, (20.0, 30.0)


def _setup() -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]], np.ndarray, Quad]:
    """The synthetic tag's exact image points, the triangle side lines through each, the corners."""
    pts = syn.image_points(SIDE, ORIGIN)
    lines = []
    for i in range(len(pts)):
        tri = next(t for t in syn.TRIANGLES if i in t)
        normals, offsets = [], []
        for j in tri:
            if j == i:
                continue
            d = pts[j] - pts[i]
            n = np.array([-d[1], d[0]]) / np.hypot(d[0], d[1])
            normals.append(n)
            offsets.append(float(n @ pts[i]))
        lines.append((np.array(normals), np.array(offsets)))
    x, y = ORIGIN
    corners = np.array([[x, y], [x + SIDE, y], [x + SIDE, y + SIDE], [x, y + SIDE]])
    return pts, lines, corners, Quad("normal", corners, SIDE * SIDE)


def _catalogue(lookup: MemoryLookup, **params: object) -> Catalogue:
    return Catalogue(lookup, frozenset(lookup.ks), DetectorParams(**params))  # type: ignore[arg-type]


def test_exact_points_identify_and_verify() -> None:
    pts, lines, corners, quad = _setup()
    res = identify(pts, lines, corners, quad, _catalogue(syn.lookup()), StageClock())
    assert isinstance(res, Detection)
    assert (res.lambda_text, res.order_type_id, res.tag, res.polarity) == (syn.lambda_text(), 7, 3, "normal")
    assert res.reprojection_error_px is not None and res.reprojection_error_px < 1e-6
    assert np.allclose(res.corners, corners)  # top-left first: the tag plane is not rotated


def test_rejections_before_verification() -> None:
    pts, lines, corners, quad = _setup()
    cat = _catalogue(syn.lookup())
    rej = identify(pts[:2], lines[:2], corners, quad, cat, StageClock())
    assert isinstance(rej, Rejection) and rej.reason == "point_count"
    flat = pts.copy()
    flat[2] = 0.5 * (flat[0] + flat[1])  # collinear with points 0 and 1
    rej = identify(flat, lines, corners, quad, cat, StageClock())
    assert isinstance(rej, Rejection) and rej.reason in ("general_position", "low_margin")
    rej = identify(pts, lines, corners, quad, _catalogue(MemoryLookup([]), allow_unknown=False), StageClock())
    assert isinstance(rej, Rejection) and rej.reason == "point_count"  # the lookup holds no 6-point sets
    unknown = identify(pts, lines, corners, quad, _catalogue(MemoryLookup([]), allow_unknown=True), StageClock())
    assert isinstance(unknown, Detection) and unknown.order_type_id is None and unknown.homography is None


def test_dictionary_polarity() -> None:
    pts, lines, corners, quad = _setup()
    both = _catalogue(syn.lookup({"tags": {"normal": 11, "inverted": 12}}))
    res = identify(pts, lines, corners, quad, both, StageClock())
    assert isinstance(res, Detection) and res.tag == 11
    inverted_only = _catalogue(syn.lookup({"tags": {"inverted": 12}}))
    rej = identify(pts, lines, corners, quad, inverted_only, StageClock())
    assert isinstance(rej, Rejection) and rej.reason == "polarity_not_in_dictionary"
    assert rej.lambda_text == syn.lambda_text() and rej.detail == "member only as inverted"


def test_low_margin_without_verification_is_rejected() -> None:
    pts, lines, corners, quad = _setup()
    res = identify(pts, lines, corners, quad, _catalogue(syn.lookup(), min_margin_px=1e6, verify=False), StageClock())
    assert isinstance(res, Rejection) and res.reason == "low_margin" and res.lambda_text == syn.lambda_text()


def test_an_id_refused_as_not_printed_must_show_its_print_at_any_view() -> None:
    """Head-on and large, a tag drawn with other triangles than the stored ones reads; once a
    reading of the data area was refused as not showing that ID as printed, it must show it."""
    pts, lines, corners, quad = _setup()
    entry = syn.lookup().get(syn.lambda_text())
    assert entry is not None
    elsewhere = replace(entry, layouts=(((0, 1, 2),),))  # triangles this drawing does not have
    cat = _catalogue(MemoryLookup([elsewhere]))
    assert isinstance(identify(pts, lines, corners, quad, cat, StageClock()), Detection)
    rej = identify(pts, lines, corners, quad, cat, StageClock(), frozenset({syn.lambda_text()}))
    assert isinstance(rej, Rejection) and rej.reason == "verification"
    assert rej.not_printed == frozenset({syn.lambda_text()})
    other = identify(pts, lines, corners, quad, cat, StageClock(), frozenset({"8:0"}))
    assert isinstance(other, Detection)  # only the IDs refused before
