"""Tags drawn by other programs: the same point set with other triangles.

With ``verify=False`` (``decode --no-verify``) the order type alone decides, as the paper does:
such a drawing reads at any size and view. With verification, views with few pixels across the
triangles (small, or oblique and small along the foreshortened direction) must still show the
stored print (the guard against readings that lost a vertex); elsewhere the points decide.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import Detector, DetectorParams
from ottag_db.printing import scenes as sc
from ottag_db.printing.scenes import DrawableTag


def _crosses(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """Whether the open segments ab and cd cross (screen orientation; general position)."""

    def turn(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> float:
        return float((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    return turn(a, b, c) * turn(a, b, d) < 0 and turn(c, d, a) * turn(c, d, b) < 0


def _inside(p: np.ndarray, tri: np.ndarray) -> bool:
    """Whether ``p`` lies inside the triangle ``tri`` (``(3, 2)``)."""
    turns = [
        (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        for a, b in zip(tri, np.roll(tri, -1, 0), strict=True)
    ]
    return all(t > 0 for t in turns) or all(t < 0 for t in turns)


def _other_drawing(tag: DrawableTag) -> DrawableTag | None:
    """The 6-point tag drawn as two disjoint triangles other than its stored layout, or None."""
    pts = tag.points
    stored = {frozenset(t) for t in tag.triangles}
    for first in itertools.combinations(range(6), 3):
        second = tuple(i for i in range(6) if i not in first)
        if first > second or {frozenset(first), frozenset(second)} == stored:
            continue
        a, b = pts[list(first)], pts[list(second)]
        edges_cross = any(_crosses(a[i], a[(i + 1) % 3], b[j], b[(j + 1) % 3]) for i in range(3) for j in range(3))
        if not edges_cross and not any(_inside(p, b) for p in a) and not any(_inside(p, a) for p in b):
            return replace(tag, triangles=(first, second))
    return None


@pytest.fixture(scope="module")
def foreign(bundled):
    """The bundled lookup and the first 6-point tags that can be drawn with other triangles."""
    lookup, tags = bundled
    drawn = [d for d in (_other_drawing(t) for t in tags if t.k == 6) if d is not None]
    return lookup, drawn[:4]


@pytest.mark.parametrize(("width_px", "tilt_deg"), [(50.0, 20.0), (120.0, 65.0)])
def test_without_verification_the_order_type_alone_decides(foreign, width_px, tilt_deg):
    """A small or oblique view of another drawing reads with ``verify=False``; verified, it is
    never misread (mostly refused because the detected triangles are not the stored layout)."""
    lookup, drawn = foreign
    assert len(drawn) == 4
    loose = Detector(lookup, DetectorParams(verify=False))
    strict = Detector(lookup)
    read_loose = verified_as_drawn = 0
    for i, tag in enumerate(drawn):
        spec = sc.posed_spec(tag, np.random.default_rng(i), width_px, tilt_deg)
        image = sc.render_scene((480, 640), [spec], np.random.default_rng(i), blur=0.5).image
        got = [d.lambda_text for d in loose.detect(image)]
        assert got in ([], [tag.lambda_text])  # never another order type
        read_loose += got == [tag.lambda_text]
        dets, rejected = strict.detect_with_rejections(image)
        assert [d.lambda_text for d in dets] in ([], [tag.lambda_text])
        refused_as_not_printed = any(r.reason == "verification" and r.lambda_text == tag.lambda_text for r in rejected)
        verified_as_drawn += bool(dets) or refused_as_not_printed
    assert read_loose >= 3
    assert verified_as_drawn >= 2


@pytest.mark.parametrize("polarity", ["normal", "inverted"])
def test_verified_a_large_oblique_view_of_another_drawing_reads(foreign, polarity):
    """At 66° a tag 220 px wide head-on keeps about 89 px across its foreshortened direction, as
    many as a head-on tag of that side: the points decide, and the other drawing reads with
    verification (refused as not printed before: foreshortened to under a half). Two of the four
    drawings end a triangle in a sliver tip whose vertex the view does not fix: their points lie
    off the fit, and such a reading must show its print at any view. With the drawn order types
    missing from the lookup nothing reads there (no look-alike)."""
    lookup, drawn = foreign
    strict = Detector(lookup)
    missing = {t.lambda_text for t in drawn}
    without = Detector(MemoryLookup(e for e in lookup if e.lambda_text not in missing))
    read = 0
    for i, tag in enumerate(drawn):
        spec = sc.posed_spec(tag, np.random.default_rng(10 + i), 220.0, 66.0, polarity)
        image = sc.render_scene((480, 640), [spec], np.random.default_rng(i), blur=0.5, noise=1.5).image
        got = [d.lambda_text for d in strict.detect(image)]
        assert got in ([], [tag.lambda_text])
        read += got == [tag.lambda_text]
        assert without.detect(image) == []
    assert read >= 2


@pytest.mark.parametrize("polarity", ["normal", "inverted"])
def test_another_drawing_at_the_frames_edge_reads_from_its_points(foreign, polarity):
    """Another drawing whose corner lies 1–3 px beyond the frame's edge: only the frame hides a
    sliver of its border, no triangle, so its points decide as for a border seen whole (refused
    before as a partly hidden data area that must show its print: none of the 6 in either
    polarity read). With the drawn order types missing from the lookup nothing reads there."""
    lookup, drawn = foreign
    strict = Detector(lookup)
    missing = {t.lambda_text for t in drawn}
    without = Detector(MemoryLookup(e for e in lookup if e.lambda_text not in missing))
    unit = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    read = tried = 0
    for i, tag in enumerate(drawn * 2):
        spec = sc.posed_spec(tag, np.random.default_rng(20 + i), 200.0, 25.0, polarity)
        truth = sc.project(spec.homography, unit)
        left = int(truth[:, 0].argmin())
        if np.sort(truth[:, 0])[1] - truth[left, 0] < 15:
            continue  # square to the frame's axes: a whole side would lie along the edge
        beyond = 1.0 + i % 3
        shift = np.array([[1.0, 0, -beyond - truth[left, 0]], [0, 1, 0], [0, 0, 1]])
        moved = sc.TagSpec(spec.points, spec.triangles, shift @ spec.homography, polarity,
                           lambda_text=spec.lambda_text, placement=spec.placement)  # fmt: skip
        image = sc.render_scene((480, 640), [moved], np.random.default_rng(i), blur=0.5, noise=1.5).image
        got = [d.lambda_text for d in strict.detect(image)]
        assert got in ([], [tag.lambda_text])
        tried += 1
        read += got == [tag.lambda_text]
        assert without.detect(image) == []
    assert tried >= 6 and read == tried
