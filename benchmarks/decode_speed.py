"""Decode speed: Order Type Tag decoder vs cv2.aruco.ArucoDetector on the same 640×480 scenes.

Usage: python benchmarks/decode_speed.py [frames] [cv2_threads]
Runs twice: with OpenCV's default thread count (``cv2_threads`` if given), where ArUco may use
every core while our decoder's Python work runs on one, and with one OpenCV thread.
Each scene is rendered twice with the same pose, blur, noise, light and JPEG: once with an Order
Type Tag (k = 8, project layout and placement), once with an ArUco 6×6 marker of the same
data-area size. Prints ms/frame for both detectors and the ratio (target ≤ 1.0), and our
decoder's time on the ArUco frames, where no tag is in view (the cost of clutter: markers, text),
then where our time goes: ms/frame per decoder stage (``Detector.detect_with_report``, one
more pass over each set of frames with one OpenCV thread).
The tags and the decoder's lookup (k = 5 … 8) come from the bundled data, imported with mirrors
(every order type) into a temporary SQLite file and read back as ``ottag-db`` reads them.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import STAGES, Detector
from ottag_db.files.bundled import bundled_point_files
from ottag_db.printing import scenes
from ottag_db.store.db import open_database
from ottag_db.store.importer import import_point_file
from ottag_db.store.lookups import load_lookup
from ottag_db.store.tags import TagRecord, select_tags

#: Point counts of the decoder's lookup (k = 3 and 4 tags are not drawn).
LOOKUP_KS = (5, 6, 7, 8)


def bundled_tags(folder: Path, ks: Sequence[int] = LOOKUP_KS) -> tuple[MemoryLookup, list[TagRecord]]:
    """Import the bundled data into a new SQLite file in ``folder``; its lookup and tags.

    Parameters
    ----------
    folder : Path
        An existing folder for the database file (a temporary one).
    ks : sequence of int
        Point counts of the lookup and of the tags.

    Returns
    -------
    lookup : MemoryLookup
        Every order type of those k (mirrors included) with its realizations.
    tags : list of TagRecord
        Each order type's tag as ``export`` prints it (stored layout and placement).
    """
    db = open_database(folder / "bundled.sqlite")
    try:
        for path, k in bundled_point_files():
            import_point_file(db, path, n=k, with_mirrors=True)
        return load_lookup(db, ks=ks), select_tags(db, ks=ks)
    finally:
        db.close()


def drawable(tag: TagRecord) -> scenes.DrawableTag:
    """The tag as the scene renderer draws it (points in canonical label order)."""
    return scenes.drawable_from_file_order(
        tag.lambda_text, tag.points, tag.labeling, tag.triangles, tag.placement, tag.printed_mp_unit
    )


def make_scenes(frames: int) -> tuple[MemoryLookup, list[np.ndarray], list[np.ndarray]]:
    """Lookup and the paired frames (Order Type Tag, ArUco marker) of the benchmark."""
    with tempfile.TemporaryDirectory() as tmp:
        lookup, records = bundled_tags(Path(tmp))
    tags = [drawable(t) for t in records if t.k == 8]
    rng = np.random.default_rng(7)
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    marker = cv2.aruco.generateImageMarker(dictionary, 5, 400)
    marker = cv2.copyMakeBorder(marker, 100, 100, 100, 100, cv2.BORDER_CONSTANT, value=255)
    ours_imgs: list[np.ndarray] = []
    aruco_imgs: list[np.ndarray] = []
    while len(ours_imgs) < frames:
        tag = tags[int(rng.integers(len(tags)))]
        w_min = scenes.min_width_px(tag.printed_mp_unit)
        if w_min > 180:
            continue
        width = rng.uniform(max(90.0, w_min), 200)
        spec = scenes.posed_spec(tag, rng, width, rng.uniform(0, 45))
        cond = {"blur": rng.uniform(0, 1), "noise": rng.uniform(0, 4), "gradient": rng.uniform(0, 0.4), "jpeg": 80}
        seed = int(rng.integers(1 << 30))
        ours_imgs.append(scenes.render_scene((480, 640), [spec], np.random.default_rng(seed), **cond).image)
        # The marker patch has a white border of 1/4 of the marker's side on each side.
        hom_m = spec.homography @ np.array([[1.5, 0, -0.25], [0, 1.5, -0.25], [0, 0, 1.0]])
        aruco_imgs.append(
            scenes.render_scene((480, 640), [], np.random.default_rng(seed), extra=[(marker, hom_m)], **cond).image
        )
    return lookup, ours_imgs, aruco_imgs


def stage_split(det: Detector, images: Sequence[np.ndarray]) -> dict[str, float]:
    """ms/frame spent in each decoder stage over ``images`` (one pass, as the detector reports it)."""
    spent = dict.fromkeys(STAGES, 0.0)
    for img in images:
        for stage, seconds in det.detect_with_report(img).timings:
            spent[stage] += seconds
    return {stage: seconds / len(images) * 1000 for stage, seconds in spent.items()}


def _timed(run: Callable[[], int], frames: int) -> tuple[float, int]:
    """ms/frame of one pass over the frames and the number of frames decoded."""
    t0 = time.perf_counter()
    found = run()
    return (time.perf_counter() - t0) / frames * 1000, found


def main(frames: int = 100, passes: int = 5) -> None:
    lookup, ours_imgs, aruco_imgs = make_scenes(frames)
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    det = Detector(lookup)
    aruco = cv2.aruco.ArucoDetector(dictionary, cv2.aruco.DetectorParameters())
    for img in ours_imgs[:5]:
        det.detect(img)
    for img in aruco_imgs[:5]:
        aruco.detectMarkers(img)

    def run_ours() -> int:
        return sum(len(det.detect(img)) > 0 for img in ours_imgs)

    def run_aruco() -> int:
        return sum(aruco.detectMarkers(img)[1] is not None for img in aruco_imgs)

    def run_ours_on_markers() -> int:  # frames without a tag: what clutter costs
        return sum(len(det.detect(img)) for img in aruco_imgs)

    threads = cv2.getNumThreads()
    results: list[tuple[float, int, float, int, float, int]] = []
    rounds = (threads, 1) if threads > 1 else (threads,)
    for n in rounds:
        cv2.setNumThreads(n)
        # interleaved rounds: both detectors see the same load on the machine
        best_o = best_a = best_m = float("inf")
        found_o = found_a = found_m = 0
        for _ in range(passes):  # best of several passes: other processes share the cores
            ms_o, found_o = _timed(run_ours, frames)
            ms_a, found_a = _timed(run_aruco, frames)
            ms_m, found_m = _timed(run_ours_on_markers, frames)
            best_o, best_a, best_m = min(best_o, ms_o), min(best_a, ms_a), min(best_m, ms_m)
        results.append((best_o, found_o, best_a, found_a, best_m, found_m))
    cv2.setNumThreads(1)
    split_tags, split_markers = stage_split(det, ours_imgs), stage_split(det, aruco_imgs)
    cv2.setNumThreads(threads)
    print(f"frames: {frames} (640×480, data area 90–200 px, tilt ≤ 45°, blur/noise/light/JPEG 80), best of {passes}")
    for n, (ms_o, found_o, ms_a, found_a, ms_m, found_m) in zip(rounds, results, strict=True):
        print(f"OpenCV threads: {n}")
        print(f"  ours : {ms_o:6.2f} ms/frame  decoded {found_o}/{frames}")
        print(f"  ArUco: {ms_a:6.2f} ms/frame  decoded {found_a}/{frames}")
        print(f"  ratio ours/ArUco: {ms_o / ms_a:.2f}")
        print(f"  ours on the ArUco frames (no tag): {ms_m:6.2f} ms/frame, {found_m} detections")
    print("our stages, ms/frame (one OpenCV thread): tag frames / ArUco frames")
    for stage in STAGES:
        print(f"  {stage:<13} {split_tags[stage]:6.3f} / {split_markers[stage]:6.3f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("frames", type=int, nargs="?", default=100, help="scenes per detector (default 100)")
    parser.add_argument("cv2_threads", type=int, nargs="?", default=None, help="OpenCV's default thread count")
    args = parser.parse_args()
    if args.frames < 1:
        parser.error("frames must be at least 1")
    if args.cv2_threads is not None:
        cv2.setNumThreads(args.cv2_threads)
    main(args.frames)
