"""Per-stage timings: the clock and the detector's report."""

from __future__ import annotations

import time

from ottag_db.decode import STAGES, Detector
from ottag_db.decode.profile import StageClock
from tests.support import synthetic_tags as syn


def test_clock_charges_each_lap_to_its_stage() -> None:
    clock = StageClock()
    time.sleep(0.01)
    clock.lap("candidates")
    clock.lap("refine")
    timings = dict(clock.timings())
    assert [s for s, _ in clock.timings()] == list(STAGES)
    assert timings["candidates"] >= 0.009 and timings["refine"] < timings["candidates"]
    assert timings["verify"] == 0.0


def test_detect_with_report() -> None:
    image = syn.draw_tags((300, 400), [(200, (40, 50))])
    det = Detector(syn.lookup())
    t0 = time.perf_counter()
    report = det.detect_with_report(image)
    wall = time.perf_counter() - t0
    assert [d.lambda_text for d in report.detections] == [syn.lambda_text()]
    dets, rejected = det.detect_with_rejections(image)
    assert [d.points.tobytes() for d in dets] == [d.points.tobytes() for d in report.detections]
    assert [(r.reason, r.detail) for r in rejected] == [(r.reason, r.detail) for r in report.rejected]
    assert [s for s, _ in report.timings] == list(STAGES)
    spent = dict(report.timings)
    assert all(v >= 0 for v in spent.values())
    assert spent["refine"] > 0 and spent["verify"] > 0
    assert sum(spent.values()) <= wall
