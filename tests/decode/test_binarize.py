"""The candidate passes' binarizations (:mod:`ottag_db.decode.binarize`): each pass's mask and
contours at its scale."""

from __future__ import annotations

from typing import Any, get_args

import numpy as np

from ottag_db.decode import DetectorParams
from ottag_db.decode.binarize import LOCAL_PASSES, Binarization, binarize
from ottag_db.decode.candidates import find_quads
from ottag_db.decode.image import frame_departure
from ottag_db.printing import clutter
from ottag_db.printing import scenes as sc

#: A normal 8-point tag nearly edge-on (84°, a pose of the tilt sweep, as in test_edge_on.py).
_EDGE_ON = (
    "8:06543210006254311003654224304323310206",
    [[60.419384, -33.663727, 317.052953], [78.800176, -63.758253, 282.174458], [0.137874, 0.067553, 1]],
)


def _edge_on_frame(bundled: Any) -> tuple[str, np.ndarray]:
    _, records = bundled
    tag = next(t for t in records if t.lambda_text.startswith(_EDGE_ON[0]))
    spec = sc.TagSpec(tag.points, tag.triangles, np.array(_EDGE_ON[1]), "normal", placement=tag.placement)
    image = sc.render_scene(
        (480, 640), [spec], np.random.default_rng(0), blur=0.28, noise=1.16, gradient=0.1, jpeg=85
    ).image
    return tag.lambda_text, image


def test_each_pass_traces_its_mask_at_its_scale(bundled):
    """The local passes search a 640 × 480 frame at half resolution, the others at full; every
    contour has its row of the hierarchy, and only the local passes trace the holes at the
    frame's edge."""
    _, image = _edge_on_frame(bundled)
    frames = [image, *clutter.clutter_frames(np.random.default_rng(3), 2)]
    params = DetectorParams()
    for gray in frames:
        departure = frame_departure(gray)
        for kind in get_args(Binarization):
            traced = binarize(gray, kind, params, departure)
            assert traced is not None and traced.kind == kind
            local = kind in LOCAL_PASSES
            assert traced.scale == (2 if local else 1)
            assert traced.mask.shape == (480 // traced.scale, 640 // traced.scale)
            assert traced.min_len == 4 * params.min_quad_side_px / traced.scale
            assert traced.hierarchy is not None and traced.hierarchy.shape == (len(traced.contours), 4)
            assert local or traced.edge_holes == ()


def test_otsu_has_no_mask_on_a_frame_without_contrast():
    """Otsu's pass, on a frame that departs nowhere by ``min_contrast``, traces nothing."""
    flat = np.full((480, 640), 128, np.uint8)
    assert binarize(flat, "otsu", DetectorParams()) is None
    assert find_quads(flat, "otsu", DetectorParams()) == []
