"""Clutter: what frames without a tag cost our decoder, against cv2.aruco.ArucoDetector on the same frames.

Usage: python benchmarks/decode_clutter.py [frames]

Three sets of 640×480 frames (``ottag_db.printing.clutter``), none holding an Order Type Tag:
- *patterns*: three flat patches per frame (ArUco 6×6, AprilTag 36h11 and ArUco 4×4 markers,
  checkerboards, white text), tilt 0–50° — the decoder tests' negatives (seed 11);
- *noise*: uniform grey-level noise, plain and blurred (σ 3 px);
- *blank*: a flat grey (15–240) with sensor noise (σ 1–4): a blank wall, a lens cap;
- *oblique markers*: one ArUco 6×6 marker tilted 76–88°, where our decoder also reads failed
  candidates in a rectified view and by model.
Prints, per set, ms/frame of both detectors with OpenCV's default threads (best of two passes),
our detections (must be 0; ArUco's own markers are its detections) and our time per stage
(``Detector.detect_with_report``). The lookup is the bundled data, k = 5 … 8 with mirrors.
"""

from __future__ import annotations

import argparse
import functools
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode import Detector
from ottag_db.printing import clutter

sys.path.insert(0, str(Path(__file__).resolve().parent))
from decode_speed import bundled_tags, stage_split  # the benchmark next door


def _ours_found(det: Detector, imgs: Sequence[NDArray[np.uint8]]) -> int:
    """Our detections in ``imgs``."""
    return sum(len(det.detect(im)) for im in imgs)


def _aruco_found(aruco: cv2.aruco.ArucoDetector, imgs: Sequence[NDArray[np.uint8]]) -> int:
    """The frames of ``imgs`` where ArUco finds a marker."""
    return sum(aruco.detectMarkers(im)[1] is not None for im in imgs)


def _best_ms(run: Callable[[], int], frames: int, passes: int = 2) -> tuple[float, int]:
    """Best ms/frame over ``passes`` runs, and what the last run counted."""
    best, count = float("inf"), 0
    for _ in range(passes):
        t0 = time.perf_counter()
        count = run()
        best = min(best, (time.perf_counter() - t0) / frames * 1000)
    return best, count


def main(frames: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        lookup, _ = bundled_tags(Path(tmp))
    det = Detector(lookup)
    aruco = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250), cv2.aruco.DetectorParameters()
    )
    sets: list[tuple[str, list[NDArray[np.uint8]]]] = [
        ("patterns", list(clutter.clutter_frames(np.random.default_rng(11), frames))),
        ("noise", list(clutter.noise_frames(np.random.default_rng(11), max(1, frames // 8)))),
        ("blank", list(clutter.blank_frames(np.random.default_rng(11), max(1, frames // 4)))),
        ("oblique markers", list(clutter.oblique_marker_frames(np.random.default_rng(11), max(1, frames // 2)))),
    ]
    print(f"OpenCV threads: {cv2.getNumThreads()}; ms/frame, best of 2 passes")
    print(f"{'set':16s} {'frames':>6s} {'ours':>8s} {'ArUco':>8s} {'ratio':>6s}  ours: detections, ms/frame per stage")
    for name, imgs in sets:
        det.detect(imgs[0])
        aruco.detectMarkers(imgs[0])
        ms_o, found = _best_ms(functools.partial(_ours_found, det, imgs), len(imgs))
        ms_a, _ = _best_ms(functools.partial(_aruco_found, aruco, imgs), len(imgs))
        spent = ", ".join(f"{s} {ms:.1f}" for s, ms in stage_split(det, imgs).items() if ms >= 0.05)
        print(f"{name:16s} {len(imgs):6d} {ms_o:8.2f} {ms_a:8.2f} {ms_o / ms_a:6.1f}  {found}; {spent}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("frames", type=int, nargs="?", default=25, help="pattern frames (default 25)")
    args = parser.parse_args()
    if args.frames < 1:
        parser.error("frames must be at least 1")
    main(args.frames)
