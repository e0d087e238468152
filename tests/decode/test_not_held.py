"""A tag the lookup does not hold: its points decide, and no stored tag is read by model in its place."""

from __future__ import annotations

import numpy as np

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import Detector
from ottag_db.decode.quads import within_detection
from ottag_db.decode.types import Quad
from ottag_db.printing import scenes as sc


def test_a_tag_the_lookup_does_not_hold_is_not_read_by_model(printed) -> None:
    """Foreshortened tags (62–72°, 120 px frontal) read with a lookup that lacks them, as a
    dictionary that lacks them would: the points read each one's order type clearly
    (``unknown_id``), and reading by model, which chooses among the stored tags only, is not
    tried there — it would read the stored tag most like the one seen."""
    lookup, tags = printed
    rng = np.random.default_rng(11)
    not_held = 0
    for i in range(12):
        tag = tags[i % len(tags)]
        without = Detector(MemoryLookup(e for e in lookup if e.lambda_text != tag.lambda_text))
        spec = sc.posed_spec(tag, rng, 120.0, float(rng.uniform(62, 72)), "inverted" if i % 2 else "normal")
        image = sc.render_scene((480, 640), [spec], rng, blur=0.5, noise=2.0, jpeg=90).image
        found, rejected = without.detect_with_rejections(image)
        assert found == []
        not_held += any(r.reason == "unknown_id" and r.lambda_text == tag.lambda_text for r in rejected)
        assert not [r.detail for r in rejected if "by model" in r.detail]
    assert not_held >= 8


def test_a_piece_of_a_tag_not_held_lies_within_it() -> None:
    """The detector skips reading by model inside a data area whose points read a tag the
    lookup does not hold, as inside a decoded one (a triangle outlined as a quad is no tag)."""
    held_out = Quad("inverted", np.array([[100, 100], [200, 100], [200, 160], [100, 160.0]]), 6000.0)
    piece = Quad("normal", np.array([[140, 120], [160, 120], [160, 135], [140, 135.0]]), 300.0)
    elsewhere = Quad("normal", np.array([[300, 120], [320, 120], [320, 135], [300, 135.0]]), 300.0)
    assert within_detection(piece, [held_out])
    assert not within_detection(elsewhere, [held_out])
