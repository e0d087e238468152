"""The printed-placement check: at oblique views a reading must lie where its tag printed it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.decode import Detector, DetectorParams
from ottag_db.decode.placement_check import (
    apply_homography,
    data_area_depths,
    placement_error,
    square_homography,
)
from ottag_db.decode.quads import squeeze
from ottag_db.decode.types import Detection, Quad, Rejection
from ottag_db.decode.verify import line_system, verify
from ottag_db.printing import scenes as sc
from ottag_db.printing.scenes import DrawableTag, drawable_from_file_order
from ottag_db.store.db import open_database
from ottag_db.store.lookups import load_lookup
from ottag_db.store.tags import select_tags

SRC = np.array([[0, 0], [100, 10], [40, 90], [120, 120], [200, 60], [160, 200.0]])
#: The placement the tag was printed with (grid → data-area units).
PRINTED = np.array([[0.004, 0.0, 0.1], [0.0, 0.004, 0.1]])
#: Another placement of the same points: fits them by a free homography just as well.
OTHER = np.array([[0.0022, 0.0006, 0.5], [-0.0004, 0.0024, 0.45]])
#: Data area → image: a strongly foreshortened view (squeeze ≈ 0.11, a side about 74 px).
VIEW = np.array([[240.0, 30.0, 100.0], [10.0, 70.0, 200.0], [0.0, 0.2, 1.0]])


def _lines_through(pts: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Two lines through every point (towards its two neighbours in the list)."""
    out = []
    for i in range(len(pts)):
        normals, offsets = [], []
        for j in ((i + 1) % len(pts), (i + 2) % len(pts)):
            d = pts[j] - pts[i]
            n = np.array([-d[1], d[0]]) / np.hypot(d[0], d[1])
            normals.append(n)
            offsets.append(float(n @ pts[i]))
        out.append((np.array(normals), np.array(offsets)))
    return out


def _printed_view() -> tuple[np.ndarray, np.ndarray, Quad]:
    """The detected points and corners of the tag printed with ``PRINTED``, seen by ``VIEW``."""
    dst = apply_homography(VIEW, SRC @ PRINTED[:, :2].T + PRINTED[:, 2])
    corners = apply_homography(VIEW, np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]))
    (ax, ay), (bx, by) = corners[2] - corners[0], corners[3] - corners[1]
    quad = Quad("normal", corners, 0.5 * abs(float(ax * by - ay * bx)))
    return dst, corners, quad


def test_square_homography_and_placement_error_are_exact() -> None:
    dst, corners, _ = _printed_view()
    h = square_homography(corners)
    assert h is not None and np.allclose(h, VIEW / VIEW[2, 2])
    system = line_system(_lines_through(dst))
    assert system is not None
    right = placement_error(PRINTED, SRC, dst, (system.nrm, system.off), system.owner, corners)
    assert right.image_px < 1e-6 and right.plane < 1e-9
    wrong = placement_error(OTHER, SRC, dst, (system.nrm, system.off), system.owner, corners)
    assert wrong.image_px > 10 and wrong.plane > 0.2
    # a rotated corner order is another tag pose: the printed points are elsewhere
    turned = placement_error(PRINTED, SRC, dst, (system.nrm, system.off), system.owner, np.roll(corners, 1, axis=0))
    assert turned.plane > 0.2
    assert square_homography(np.zeros((4, 2))) is None


def test_verify_checks_the_printed_placement() -> None:
    dst, corners, quad = _printed_view()
    assert squeeze(quad) < 0.2  # a grazing view: where a free homography fits another placement
    lines = _lines_through(dst)
    ident = [tuple(range(6))]

    def entry(*placements: np.ndarray) -> LookupEntry:
        return LookupEntry("6:x", 6, 1, True, (SRC,), placements=placements)

    ok = verify(entry(PRINTED), dst, lines, ident, corners, quad, 5.0, "6:x", DetectorParams())
    assert isinstance(ok, Detection) and ok.reprojection_error_px is not None and ok.reprojection_error_px < 1e-6
    rej = verify(entry(OTHER), dst, lines, ident, corners, quad, 5.0, "6:x", DetectorParams())
    assert isinstance(rej, Rejection) and rej.reason == "verification" and "printed placement" in rej.detail
    # the fit alone accepts it: without a known placement (a portable dictionary file) the
    # reading stands
    assert isinstance(verify(entry(), dst, lines, ident, corners, quad, 5.0, "6:x", DetectorParams()), Detection)
    # a realization whose placement is unknown is judged by its fit alone
    mixed = LookupEntry("6:x", 6, 1, True, (SRC, SRC.copy()), placements=(OTHER, None))
    assert isinstance(verify(mixed, dst, lines, ident, corners, quad, 5.0, "6:x", DetectorParams()), Detection)


@pytest.fixture(scope="module")
def six_point(bundled_db_path) -> tuple[MemoryLookup, DrawableTag]:
    """The k = 6 lookup (with stored placements) and its largest-MP tag as ``export`` draws it."""
    db = open_database(bundled_db_path)
    try:
        lookup = load_lookup(db, ks=(6,))
        best = max(select_tags(db, ks=(6,)), key=lambda t: t.mp)
    finally:
        db.close()
    tag = drawable_from_file_order(
        best.lambda_text, best.points, best.labeling, best.triangles, best.placement, best.printed_mp_unit
    )
    return lookup, tag


def _oblique(tag: DrawableTag, seed: int, side: float = 120.0) -> np.ndarray:
    """The tag at 68°, ``side`` px head-on (120: 45 px across the foreshortened direction)."""
    rng = np.random.default_rng(seed)
    spec = sc.posed_spec(tag, rng, side, 68.0)
    return sc.render_scene((480, 640), [spec], rng, blur=0.4, noise=1.5).image


def test_lookup_carries_the_stored_placements(six_point) -> None:
    lookup, tag = six_point
    entry = lookup.get(tag.lambda_text)
    assert entry is not None and len(entry.placements) == len(entry.realizations)
    assert all(p is not None and p.shape == (2, 3) for p in entry.placements)
    assert any(np.allclose(p, tag.placement) for p in entry.placements if p is not None)


def test_rendered_oblique_tag_reads_only_as_printed(six_point) -> None:
    lookup, tag = six_point
    det = Detector(lookup)
    seeds = range(3)
    for seed in seeds:
        found = det.detect(_oblique(tag, seed))
        assert [d.lambda_text for d in found] == [tag.lambda_text]
    # the same points printed with another placement (shrunk into a corner and sheared):
    # every triangle and the order type are the tag's, only the placement disagrees
    lin, off = np.array([[0.55, 0.1], [-0.05, 0.6]]), np.array([0.05, 0.08])
    m = tag.placement
    moved = dataclasses.replace(tag, placement=np.c_[lin @ m[:, :2], lin @ m[:, 2] + off])
    for seed in seeds:
        found, rejected = det.detect_with_rejections(_oblique(moved, seed))
        assert found == []
        assert any(r.reason == "verification" and "printed placement" in r.detail for r in rejected)
        # a larger view keeps as many pixels across as a head-on tag of 75 px: the points decide
        assert [d.lambda_text for d in det.detect(_oblique(moved, seed, side=200.0))] == [tag.lambda_text]
    # a lookup that knows no placement (a portable dictionary file) reads it
    entries = [dataclasses.replace(e, placements=()) for e in lookup]
    loose = Detector(MemoryLookup(entries))
    assert any(d.lambda_text == tag.lambda_text for d in loose.detect(_oblique(moved, 0)))


def test_data_area_depths_tell_a_view_from_a_map_across_the_horizon() -> None:
    """w of the four corners: one sign for a view; the horizon y = 0.5 splits the data area."""
    view = np.array([[40.0, 0, 9.5], [0, 40.0, 9.5], [0, -0.5, 1.0]])  # horizon at y = 2
    np.testing.assert_allclose(data_area_depths(view), [1.0, 1.0, 0.5, 0.5])
    assert (data_area_depths(-view) < 0).all()  # the same view, the other sign of scale
    across = np.array([[40.0, 0, 9.5], [0, 40.0, 9.5], [0, -2.0, 1.0]])
    depth = data_area_depths(across)
    assert depth.min() < 0 < depth.max()
