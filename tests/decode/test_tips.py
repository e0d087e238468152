"""Sharp tips measured at their apex, and near-symmetric point sets drawn with other triangles."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from ottag_db.decode import Detector
from ottag_db.decode.refine import lines_through, triangle_vertices
from ottag_db.decode.tips import apices
from ottag_db.decode.types import TriangleLines
from ottag_db.printing import scenes as sc

#: An 8-point order type whose points lie nearly on an ellipse.
_NEAR_SYMMETRIC = "8:0654321000654321100654322100654332100654432100655432100665432100"


def _sliver_scene(blur: float) -> tuple[np.ndarray, np.ndarray]:
    """A bright 8° sliver on a dark ground, rendered into a frame; its vertices in frame pixels."""
    patch = np.zeros((400, 400), np.uint8)
    tri = np.array([[40.0, 200.0], [360.0, 178.0], [360.0, 222.0]])  # tip at the left, about 8°
    cv2.fillPoly(patch, [np.round(tri * 16).astype(np.int32).reshape(-1, 1, 2)], 255, shift=4)
    hom = np.array([[100.0, 0.0, 20.0], [0.0, 100.0, 15.0], [0.0, 0.0, 1.0]])  # unit square → 100 px
    image = sc.render_scene((140, 140), [], np.random.default_rng(1), blur=blur, noise=1.0, extra=[(patch, hom)]).image
    # patch pixel centres: unit = (pixel + 0.5) / 400
    truth = (tri + 0.5) / 400 * 100 + np.array([20.0, 15.0])
    return image, truth


@pytest.mark.parametrize("blur", [0.5, 1.2])
def test_a_sharp_tip_is_measured_at_its_apex_not_where_its_lines_meet(blur):
    """Side lines 0.3 px outside the sliver (as a fit of a few px wide sliver leaves them) meet
    4.3 px beyond its apex; the cross-section masses put it within a pixel although
    ``cv2.fillPoly`` fills every pixel its edges touch (the sliver about 0.25 px wider than
    drawn: the line through its masses reaches zero 1.6-1.9 px beyond the apex, where they start
    is the apex)."""
    image, truth = _sliver_scene(blur)
    normal, offset = lines_through(truth)
    centre = truth.mean(axis=0)
    outward = np.sign(normal @ centre - offset)  # + when the normal points in
    offset = offset - 0.3 * outward  # every side moved 0.3 px outward
    vertices = triangle_vertices(normal, offset)
    tris = TriangleLines(normal, offset, vertices)
    by_lines = float(np.hypot(*(vertices[0, 0] - truth[0])))
    assert by_lines > 4.0
    measured = apices(image.astype(np.float32), tris, 0.5 * (float(image.min()) + float(image.max())))
    assert set(measured) == {0}  # only the sharp tip (the other two corners are 86°)
    assert np.hypot(*(np.array(measured[0]) - truth[0])) < 1.0


def test_a_near_symmetric_tag_drawn_with_other_triangles_reads_under_the_turn_that_fits(bundled):
    """An 8-point tag with its points nearly on an ellipse: drawn with other triangles
    that match its stored layout under a wrong turn, that turn fits the side lines within the
    bound but puts the points a dozen px off; the turn whose points fit reads (head-on the
    points decide). Verified, nothing else is read."""
    lookup, tags = bundled
    tag = next(t for t in tags if t.lambda_text == _NEAR_SYMMETRIC)
    drawn = replace(tag, triangles=((2, 3, 4), (5, 6, 7), (0, 1, 7)))
    detector = Detector(lookup)
    read = 0
    for i, polarity in enumerate(("normal", "inverted")):
        spec = sc.posed_spec(drawn, np.random.default_rng(20 + i), 280.0, 20.0, polarity)
        image = sc.render_scene((480, 640), [spec], np.random.default_rng(i), blur=0.5, noise=1.5).image
        got = [d.lambda_text for d in detector.detect(image)]
        assert got in ([], [tag.lambda_text])
        read += got == [tag.lambda_text]
    assert read == 2
