"""One detector, several threads: ``detect`` keeps no state, so results do not depend on timing."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ottag_db.decode import Detection, Detector, Rejected
from tests.support import synthetic_tags as syn


def _key(result: tuple[list[Detection], list[Rejected]]) -> tuple[object, ...]:
    dets, rejected = result
    return (
        tuple((d.lambda_text, d.polarity, d.points.tobytes(), d.corners.tobytes(), d.margin_px) for d in dets),
        tuple((r.reason, r.polarity, r.corners.tobytes(), r.lambda_text, r.detail) for r in rejected),
    )


def test_detect_from_several_threads_gives_identical_results() -> None:
    frames = [
        syn.draw_tags((360, 480), [(150, (20, 30)), (120, (250, 160))]),
        syn.draw_tags((360, 480), [(200, (100, 80))], inverted=True),
        syn.draw_tags((360, 480), [(110, (30, 200)), (170, (260, 20))]),
        np.random.default_rng(1).integers(0, 256, (360, 480), dtype=np.uint8),
    ]
    det = Detector(syn.lookup())
    expected = [_key(det.detect_with_rejections(f)) for f in frames]
    assert sum(len(k[0]) for k in expected) == 5
    jobs = [i % len(frames) for i in range(32)]
    with ThreadPoolExecutor(max_workers=6) as pool:
        got = list(pool.map(lambda i: _key(det.detect_with_rejections(frames[i])), jobs))
    assert got == [expected[i] for i in jobs]
