"""Decoder: synthetic scenes (perspective, blur, noise, light, JPEG), negatives and bad input."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ottag_db.core.canonical import canonical_orderings
from ottag_db.core.geometry import maximal_perturbation
from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode.detector import REJECTION_REASONS, Detection, Detector, Rejected, _read_orderings, to_gray
from ottag_db.errors import DecodeError, OttagError, UsageError
from tests.support import tagsynth as ts

needs_ref = pytest.mark.skipif(ts.aichholzer_dir() is None, reason="OTTAG_AICHHOLZER_DIR is not set")

N_FRAMES = 170  # about 210 tags, k = 5 … 8, both polarities


@pytest.fixture(scope="module")
def reference():
    return ts.reference_lookup(ts.aichholzer_dir())  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def positive_run(reference):
    """Decode the fixed-seed positive set once; per-tag outcome records."""
    lookup, records = reference
    det = Detector(lookup)
    rng = np.random.default_rng(20180324)
    cache: dict[bytes, ts.Drawable] = {}
    outcomes = []
    stray = 0
    for f in range(N_FRAMES):
        scene = ts.random_scene(rng, records, cache, n_tags=3)
        dets = det.detect(scene.image)
        used = set()
        for spec, truth in zip(scene.tags, scene.truth_points, strict=True):
            c = truth.mean(axis=0)
            near = [i for i, d in enumerate(dets) if np.linalg.norm(d.points.mean(axis=0) - c) < 0.3 * _width(spec)]
            used.update(near)
            right = [dets[i] for i in near if dets[i].lambda_ == spec.lambda_]
            wrong = [dets[i] for i in near if dets[i].lambda_ != spec.lambda_]
            err = None
            if right and right[0].model_points is not None:
                err = float(np.linalg.norm(right[0].points - truth, axis=1).max())
            outcomes.append({"frame": f, "k": len(spec.points), "ok": bool(right), "wrong": len(wrong), "err": err})
        stray += len(dets) - len(used)
    return outcomes, stray


def _width(spec: ts.TagSpec) -> float:
    sq = ts._proj(spec.homography, np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]))
    return float(np.sqrt(abs(cv2.contourArea(sq.astype(np.float32)))))


@needs_ref
def test_no_wrong_ids(positive_run):
    outcomes, stray = positive_run
    assert sum(o["wrong"] for o in outcomes) == 0
    assert stray == 0


@needs_ref
def test_decode_rate(positive_run, capsys):
    outcomes, _ = positive_run
    n = len(outcomes)
    ok = sum(o["ok"] for o in outcomes)
    errs = [o["err"] for o in outcomes if o["err"] is not None]
    by_k = {k: (sum(o["ok"] for o in outcomes if o["k"] == k), sum(o["k"] == k for o in outcomes)) for k in range(5, 9)}
    with capsys.disabled():
        print(
            f"\ndecoder: {ok}/{n} tags decoded ({100 * ok / n:.1f} %), by k {by_k}; point error "
            f"(largest per tag) median {np.median(errs):.2f} px, 95 % {np.percentile(errs, 95):.2f} px"
        )
    assert n >= 200
    assert ok / n >= 0.99  # measured 99.0 %
    assert np.median(errs) < 1.5  # largest point error per tag, px


@needs_ref
def test_decode_rate_target(positive_run):
    outcomes, _ = positive_run
    assert sum(o["ok"] for o in outcomes) / len(outcomes) >= 0.99


@needs_ref
def test_points_and_corners_order(reference):
    lookup, records = reference
    rec = next(r for r in records if r["k"] == 7 and lookup.get(r["lambda"]).unique_min)  # type: ignore[union-attr]
    rng = np.random.default_rng(1)
    posed = ts.posed_spec(rec, rng, 220, 35)
    hom = posed.homography
    for pol in ("normal", "inverted"):
        spec = replace(posed, polarity=pol)
        scene = ts.render_scene((480, 640), [spec], rng, blur=0.7, noise=2)
        dets, rejected = Detector(lookup).detect_with_rejections(scene.image)
        assert len(dets) == 1
        d = dets[0]
        assert isinstance(d, Detection) and d.polarity == pol and d.k == 7
        assert d.lambda_ == rec["lambda"] and d.order_type_id == lookup.get(d.lambda_).order_type_id  # type: ignore[union-attr]
        assert np.abs(d.points - scene.truth_points[0]).max() < 1.0
        assert d.model_points is not None and np.allclose(d.model_points, rec["points"])
        corners = ts._proj(hom, np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]))
        assert np.abs(d.corners - corners).max() < 1.0
        assert d.reprojection_error_px is not None and d.reprojection_error_px < 1.0
        assert d.margin_px > 1.0
        assert all(isinstance(r, Rejected) and r.reason in REJECTION_REASONS for r in rejected)


@needs_ref
def test_options_verify_and_unknown(reference):
    lookup, records = reference
    rec = next(r for r in records if r["k"] == 6)
    rng = np.random.default_rng(2)
    spec = ts.posed_spec(rec, rng, 200, 20)
    image = ts.render_scene((480, 640), [spec], rng, blur=0.5).image
    # order type missing from the lookup: rejected, or reported without ids with allow_unknown
    others = MemoryLookup(e for e in lookup if e.lambda_text != rec["lambda"])  # type: ignore[attr-defined]
    det = Detector(others)
    assert det.detect(image) == []
    assert any(r.reason == "unknown_id" and r.lambda_ == rec["lambda"] for r in det.last_rejections)
    unknown = Detector(others, allow_unknown=True).detect(image)
    assert len(unknown) == 1 and unknown[0].order_type_id is None and unknown[0].homography is None
    # a realization that does not match the drawn points: verification rejects, verify=False accepts
    entry = lookup.get(rec["lambda"])
    assert entry is not None
    other = next(r for r in records if r["k"] == 6 and r["lambda"] != rec["lambda"])
    bogus = np.asarray(other["points"], dtype=np.float64)  # another order type's points
    from ottag_db.core.lookup import LookupEntry

    fake = MemoryLookup([LookupEntry(entry.lambda_text, entry.k, entry.order_type_id, entry.unique_min, (bogus,))])
    strict = Detector(fake)
    assert strict.detect(image) == []
    assert any(r.reason in ("verification", "quad_inconsistent") for r in strict.last_rejections)
    loose = Detector(fake, verify=False).detect(image)
    assert len(loose) == 1 and loose[0].lambda_ == rec["lambda"]


@needs_ref
def test_dictionary_polarity(reference):
    """A dictionary entry (``extra["tags"]``: polarity → number) reports the detected polarity's number."""
    from ottag_db.core.lookup import LookupEntry

    lookup, records = reference
    rec = next(r for r in records if r["k"] == 7)
    entry = lookup.get(rec["lambda"])
    assert entry is not None
    rng = np.random.default_rng(3)
    posed = ts.posed_spec(rec, rng, 200, 25)
    images = {
        pol: ts.render_scene((480, 640), [replace(posed, polarity=pol)], rng, blur=0.5, noise=2).image
        for pol in ("normal", "inverted")
    }

    def member(tags: dict[str, int]) -> MemoryLookup:
        return MemoryLookup([LookupEntry(entry.lambda_text, entry.k, entry.order_type_id, entry.unique_min,
                                         entry.realizations, min(tags.values()), {"tags": tags})])  # fmt: skip

    both = Detector(member({"normal": 11, "inverted": 12}))
    assert [(d.tag, d.polarity) for d in both.detect(images["normal"])] == [(11, "normal")]
    assert [(d.tag, d.polarity) for d in both.detect(images["inverted"])] == [(12, "inverted")]
    only_normal = Detector(member({"normal": 5}))
    assert [d.tag for d in only_normal.detect(images["normal"])] == [5]
    assert only_normal.detect(images["inverted"]) == []
    assert any(
        r.reason == "polarity_not_in_dictionary" and r.lambda_ == rec["lambda"] and r.polarity == "inverted"
        for r in only_normal.last_rejections
    )
    assert "polarity_not_in_dictionary" in REJECTION_REASONS


# ---------------------------------------------------------------------- negatives
def _negative_frames(seed: int, n: int):
    rng = np.random.default_rng(seed)
    k_mat = ts.camera_matrix()
    dicts = [cv2.aruco.DICT_6X6_250, cv2.aruco.DICT_APRILTAG_36h11, cv2.aruco.DICT_4X4_50]
    for i in range(n):
        patches = []
        for j in range(3):
            kind = (i + j) % 5
            if kind < 3:
                d = cv2.aruco.getPredefinedDictionary(dicts[kind])
                img = cv2.aruco.generateImageMarker(d, int(rng.integers(30)), 240)
                img = cv2.copyMakeBorder(img, 60, 60, 60, 60, cv2.BORDER_CONSTANT, value=255)
            elif kind == 3:
                sq = int(rng.integers(4, 9))
                img = ((np.indices((sq, sq)).sum(axis=0) % 2) * 255).astype(np.uint8)
                img = cv2.resize(img, (240, 240), interpolation=cv2.INTER_NEAREST)
                img = cv2.copyMakeBorder(img, 30, 30, 30, 30, cv2.BORDER_CONSTANT, value=255)
            else:
                img = np.full((200, 300), 255, np.uint8)
                cv2.rectangle(img, (20, 20), (280, 180), 0, -1)
                for row in range(3):
                    cv2.putText(img, "AVW7>4", (30, 70 + 45 * row), cv2.FONT_HERSHEY_SIMPLEX, 1.4, 255, 3)
            width = rng.uniform(80, 160)
            r_mat, t = ts.random_pose(rng, k_mat, 0.1, width, rng.uniform(0, 50), (110 + 210 * j, 240))
            patches.append((img, ts.pose_homography(k_mat, r_mat, t, 0.1)))
        scene = ts.render_scene((480, 640), [], rng, blur=rng.uniform(0, 1), noise=rng.uniform(0, 5),
                                gradient=rng.uniform(0, 0.5), jpeg=70, extra=patches)  # fmt: skip
        yield scene.image
    for _ in range(3):
        yield rng.integers(0, 256, (480, 640), dtype=np.uint8)
        yield cv2.GaussianBlur(rng.integers(0, 256, (480, 640), dtype=np.uint8), (0, 0), 3)


@needs_ref
def test_negatives(reference):
    lookup, _ = reference
    det = Detector(lookup)
    hits = []
    for image in _negative_frames(11, 25):
        hits.extend(det.detect(image))
    assert hits == []
    # even order types the lookup does not hold: no triangle points come out of markers/text
    anything = Detector(lookup, allow_unknown=True)
    assert sum(len(anything.detect(img)) for img in _negative_frames(12, 10)) == 0


# ---------------------------------------------------------------------- bad input
def test_bad_input():
    det = Detector(MemoryLookup([]))
    assert det.detect(np.zeros((0, 0), np.uint8)) == []
    assert det.detect(np.zeros((0, 5, 3), np.uint8)) == []
    assert det.detect(np.zeros((1, 1), np.uint8)) == []
    assert det.detect(np.zeros((1, 1, 3), np.uint8)) == []
    assert det.last_rejections == []
    for bad in (np.zeros((4, 4, 4, 4)), np.zeros(10), np.array([["a", "b"]]), np.zeros((5, 5, 2)), "image.png", None):
        with pytest.raises(DecodeError):
            det.detect(bad)
    assert issubclass(DecodeError, OttagError)
    with pytest.raises(UsageError):
        Detector(MemoryLookup([]), no_such_option=1)
    with pytest.raises(UsageError):
        Detector(MemoryLookup([]), polarities=("sideways",))


def test_to_gray_conversions():
    grey = np.tile(np.arange(0, 256, 16, dtype=np.uint8), (8, 1))
    assert to_gray(grey) is not None and to_gray(grey).dtype == np.uint8
    bgr = np.dstack([grey] * 3)
    assert np.array_equal(to_gray(bgr), grey)
    bgra = np.dstack([grey] * 3 + [np.full_like(grey, 255)])
    assert np.array_equal(to_gray(bgra), grey)
    assert np.array_equal(to_gray(grey[:, :, None]), grey)
    g16 = grey.astype(np.uint16) * 257
    assert np.abs(to_gray(g16).astype(int) - grey).max() <= 1
    g12 = grey.astype(np.uint16) * 16  # 12-bit data in a 16-bit array
    assert np.abs(to_gray(g12).astype(int) - grey).max() <= 1
    assert np.abs(to_gray(grey.astype(np.float32) / 255).astype(int) - grey).max() <= 1
    assert to_gray(np.ones((3, 3), bool)).max() == 255


@needs_ref
def test_sixteen_bit_and_rgba_decode(reference):
    lookup, records = reference
    rec = next(r for r in records if r["k"] == 8)
    rng = np.random.default_rng(5)
    spec = ts.posed_spec(rec, rng, 260, 15)
    image = ts.render_scene((480, 640), [spec], rng, blur=0.5).image
    det = Detector(lookup)
    expect = [d.lambda_ for d in det.detect(image)]
    assert expect == [rec["lambda"]]
    assert [d.lambda_ for d in det.detect(image.astype(np.uint16) * 257)] == expect
    rgba = cv2.cvtColor(image, cv2.COLOR_GRAY2BGRA)
    assert [d.lambda_ for d in det.detect(rgba)] == expect
    assert math.isfinite(det.detect(image)[0].margin_px)


# ---------------------------------------------------------------------- splitter internals
def test_strict_fit_splits_small_triangle_hanging_at_a_corner():
    """A small triangle touching a large one at its vertex passes the loose fit (its contour
    lies in the trimmed corner ends) but not the strict one, which splits the two apart."""
    from ottag_db.decode import detector as dec

    img = np.zeros((300, 300), np.uint8)
    big = np.array([[20, 20], [280, 140], [110, 230]], np.int32)
    small = np.array([[110, 230], [80, 232], [112, 262]], np.int32)  # shares the vertex (110, 230)
    cv2.fillPoly(img, [big, small], 255)
    contours, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    assert len(contours) == 1
    pts = contours[0].reshape(-1, 2)
    assert dec._triangle_fit(pts) is not None  # the loose fit absorbs the small triangle
    assert dec._triangle_fit(pts, strict=1.5) is None
    assert len(dec._reflex_corners(pts)) >= 1
    splits = list(dec._split_triangles(pts, 0, False, 1.5, [80]))
    assert any(len(chains) == 6 for chains in splits)  # two triangles


@needs_ref
def test_half_resolution_candidate_search_matches_full_resolution(reference):
    """The automatic local threshold searches a 640×480 frame at half resolution; small, tilted
    tags (data area ~50–70 px) decode as with the full-resolution search (explicit window)."""
    lookup, records = reference
    cache: dict[bytes, ts.Drawable] = {}
    rng = np.random.default_rng(11)
    half, full = Detector(lookup), Detector(lookup, adaptive_block=31)
    recs = [r for r in records if r["k"] in (5, 6) and ts.min_width_px(ts.drawable(r, cache).mp_unit) <= 60]
    decoded = 0
    for n in range(12):
        rec = recs[n % len(recs)]
        dr = ts.drawable(rec, cache)
        width = float(rng.uniform(ts.min_width_px(dr.mp_unit), 70))
        spec = ts.posed_spec(rec, rng, width, float(rng.uniform(0, 35)), ("normal", "inverted")[n % 2], cache)
        image = ts.render_scene((480, 640), [spec], rng, blur=0.5, noise=2).image
        a, b = half.detect(image), full.detect(image)
        assert [d.lambda_ for d in a] == [d.lambda_ for d in b]
        for da, db in zip(a, b, strict=True):
            assert np.abs(da.points - db.points).max() < 0.3
        decoded += len(a) == 1 and a[0].lambda_ == rec["lambda"]
    assert decoded >= 11


@settings(max_examples=200, deadline=None)
@given(
    st.integers(3, 8).flatmap(
        lambda k: st.lists(st.tuples(st.integers(0, 639), st.integers(0, 479)), min_size=k, max_size=k, unique=True)
    )
)
def test_read_orderings_match_the_canonical_module(points) -> None:
    """The decoder's λ (from the orientation table of its margin) and orderings equal the
    canonical module's, and its margin is twice the geometry core's MP."""
    pts = np.array(points, dtype=np.float64)
    margin, orderings = _read_orderings(pts)
    assert margin == pytest.approx(2 * maximal_perturbation(pts))
    if margin > 0:
        expected = canonical_orderings(pts)
        assert [lab for lab, _ in orderings] == [lab for lab, _ in expected]
        assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(orderings, expected, strict=True))
