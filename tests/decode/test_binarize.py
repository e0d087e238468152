"""The candidate passes' binarizations (:mod:`ottag_db.decode.binarize`): a pass outlines the same
quads from a binarization traced before as from its own."""

from __future__ import annotations

from typing import Any, get_args

import numpy as np

from ottag_db.decode import DetectorParams
from ottag_db.decode.binarize import Binarization, binarize
from ottag_db.decode.candidates import find_quads
from ottag_db.decode.image import frame_departure
from ottag_db.printing import clutter
from ottag_db.printing import scenes as sc

#: A normal 8-point tag nearly edge-on (84°, a pose of the tilt sweep, as in test_edge_on.py): the
#: passes for thin quads and bright holes outline it.
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


def _encoded(x: Any) -> Any:
    """A detector's output as plain values: arrays as their bytes, dataclasses field by field."""
    if isinstance(x, np.ndarray):
        return (x.dtype.str, x.shape, x.tobytes())
    if isinstance(x, list | tuple):
        return [_encoded(y) for y in x]
    if hasattr(x, "__dataclass_fields__"):
        return [_encoded(getattr(x, f)) for f in x.__dataclass_fields__]
    return x


def test_find_quads_of_a_binarization_traced_before_are_those_traced_now(bundled):
    """Every pass outlines the same quads from :func:`binarize`'s trace as when it traces itself."""
    _, image = _edge_on_frame(bundled)
    frames = [image, *clutter.clutter_frames(np.random.default_rng(3), 2)]
    params = DetectorParams()
    for gray in frames:
        departure = frame_departure(gray)
        for kind in get_args(Binarization):
            traced = binarize(gray, kind, params, departure)
            assert traced is None or traced.kind == kind
            now = find_quads(gray, kind, params, departure)
            assert _encoded(find_quads(gray, kind, params, departure, traced)) == _encoded(now)
