"""Grazing-angle frames of the bundled tags, shared by the rectified-retry and model tests."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.lookup import MemoryLookup
from ottag_db.core.types import Polarity
from ottag_db.printing import scenes as sc
from ottag_db.printing.scenes import DrawableTag, drawable_from_file_order
from ottag_db.store.db import open_database
from ottag_db.store.lookups import load_lookup
from ottag_db.store.tags import select_tags


def printed_tags(db_path: object) -> tuple[MemoryLookup, list[DrawableTag]]:
    """Lookup (k = 5 … 8) of a database and its 24 k = 8 tags of largest MP as ``export`` draws them."""
    db = open_database(db_path)  # type: ignore[arg-type]
    try:
        lookup = load_lookup(db, ks=(5, 6, 7, 8))
        k8 = sorted((t for t in select_tags(db, ks=(8,))), key=lambda t: -t.mp)[:24]
    finally:
        db.close()
    tags = [
        drawable_from_file_order(t.lambda_text, t.points, t.labeling, t.triangles, t.placement, t.printed_mp_unit)
        for t in k8
    ]
    return lookup, tags


def grazing_frame(
    tags: list[DrawableTag], seed: int, tilt: float, polarity: Polarity = "normal", background: int = 200
) -> tuple[DrawableTag, NDArray[np.uint8]]:
    """A 21 cm tag at 1.5 m (98 px frontal, f = 700 px) tilted ``tilt`` degrees (blur σ 0.5 px,
    noise σ 2, JPEG 90) on a frame of grey ``background``; the tag is ``tags[seed % len(tags)]``."""
    tag, spec, rng = _grazing_spec(tags, seed, tilt, polarity)
    return tag, sc.render_scene((480, 640), [spec], rng, background=background, blur=0.5, noise=2.0, jpeg=90).image


def grazing_corners(
    tags: list[DrawableTag], seed: int, tilt: float, polarity: Polarity = "normal"
) -> NDArray[np.float64]:
    """The ``(4, 2)`` data-area corners (frame pixels, tag order) of :func:`grazing_frame`'s tag."""
    _, spec, _ = _grazing_spec(tags, seed, tilt, polarity)
    return sc.project(spec.homography, np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))


def _grazing_spec(
    tags: list[DrawableTag], seed: int, tilt: float, polarity: Polarity
) -> tuple[DrawableTag, sc.TagSpec, np.random.Generator]:
    rng = np.random.default_rng(seed)
    tag = tags[seed % len(tags)]
    return tag, sc.posed_spec(tag, rng, 98.0, tilt, polarity), rng


def grazing_set() -> list[tuple[int, float, Polarity]]:
    """The grazing set: 28 frames (seed, tilt 80 … 86°, polarity), both polarities alternating."""
    out: list[tuple[int, float, Polarity]] = []
    for seed in range(100, 128):
        out.append((seed, 80.0 + (seed // 2) % 7, "normal" if seed % 2 else "inverted"))
    return out
