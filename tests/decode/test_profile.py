"""Per-stage timings: the clock and the detector's report."""

from __future__ import annotations

import time

import numpy as np

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


def test_clock_times_each_pass_from_its_start_to_the_next() -> None:
    clock = StageClock()
    assert clock.pass_timings() == ()
    clock.start_pass("adaptive")
    time.sleep(0.01)
    clock.start_pass("otsu")
    clock.end_passes()
    (first, long), (second, short) = clock.pass_timings()
    assert (first, second) == ("adaptive", "otsu")
    assert long >= 0.009 and 0 <= short < long


def test_report_times_the_passes_that_ran() -> None:
    """A frame whose tag reads in the first pass runs that pass alone; a frame without a tag runs
    the later ones too (Otsu's only where the frame has contrast), each timed once, in order."""
    det = Detector(syn.lookup())
    tag = syn.draw_tags((300, 400), [(200, (40, 50))])
    t0 = time.perf_counter()
    report = det.detect_with_report(tag)
    wall = time.perf_counter() - t0
    assert [name for name, _ in report.passes] == ["adaptive"]
    assert 0 < report.passes[0][1] <= wall
    rng = np.random.default_rng(1)
    texture = np.clip(rng.normal(128, 40, (300, 400)), 0, 255).astype(np.uint8)
    report = det.detect_with_report(texture)
    names = [name for name, _ in report.passes]
    assert report.detections == [] and names[:2] == ["adaptive", "otsu"] and "local_range" in names
    assert len(set(names)) == len(names) and all(seconds >= 0 for _, seconds in report.passes)
    assert sum(seconds for _, seconds in report.passes) <= sum(seconds for _, seconds in report.timings) + 1e-3
