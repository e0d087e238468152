"""Real photographs and textures: what frames without a tag cost, and a tag in front of them.

Usage: python benchmarks/decode_photos.py [--tags N] [--seed S] [--passes P]

Frames of scikit-image's bundled photographs and textures (``skimage.data``: people, animals,
brick, grass, gravel, text, a printed page, micrographs, …), grey, resized to 640×480 — frames
the decoder was never tuned on. Two sets, each read by ours, ArUco 6×6
(``cv2.aruco.ArucoDetector``, OpenCV's default threads) and AprilTag 3 (``pupil_apriltags``,
defaults) in the same run:

- *photographs*: the frames as they are (no tag: every detection is a false one);
- *tag on a wall*: the photograph as a wall, with one 8-point tag — and, on the peers' frames,
  their marker at the same pose and size — drawn on it at a random pose (data area 70–180 px,
  tilt ≤ 50°, camera blur, noise and JPEG 80): tags read.

Prints per set the mean and the slowest frame's ms (best of ``--passes`` runs each), the ratios
to ArUco and AprilTag, detections, and our time per stage and per candidate pass; and for the photographs each frame's
times, and ours again with settings that trade readings for time: a lookup of
:data:`SMALL_LOOKUP` order types (the size of AprilTag 36h11's family; fewer templates to read
by model), no reading by model (``DetectorParams(model_match=False)``; what it gives up:
``decode_sweeps.py --without-model``), no last-resort candidate passes
(``DetectorParams(last_resort_passes=False)``; ``decode_sweeps.py --other
last_resort_passes=false``), and neither; and, for the default and without the last-resort
passes, what the passes' thresholds and contour traces alone cost (OpenCV's work, before any
outline or reading: a floor while those passes stay). The time targets of the decoder design
(issue 37): mean ≤ 1.5 × ArUco's on the photographs and no frame there over 3 × ArUco's slowest;
≤ 1.0 × ArUco's and ≤ AprilTag's with a tag. Needs ``pip install '.[bench]'`` (scikit-image, pupil-apriltags).
"""

from __future__ import annotations

import argparse
import functools
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import STAGES, Detector, DetectorParams
from ottag_db.decode.binarize import Binarization, binarize
from ottag_db.printing import scenes

sys.path.insert(0, str(Path(__file__).resolve().parent))
from decode_speed import bundled_tags, drawable  # the benchmarks next door
from peers import MARKER_ID, PATCH_TO_DATA_AREA, PEERS, PeerReader, marker_patch

#: scikit-image's bundled images used as frames (all ship with the package; none holds a tag).
PHOTOS = (
    "astronaut", "brick", "camera", "cat", "chelsea", "clock", "coffee", "coins", "colorwheel", "grass",
    "gravel", "horse", "hubble_deep_field", "immunohistochemistry", "logo", "moon", "page", "retina",
    "rocket", "text",
)  # fmt: skip

_U8 = NDArray[np.uint8]
_Frame = TypeVar("_Frame")  # what frame_times hands each reading: a frame, or its index
#: Order types of the small lookup of the settings rows (AprilTag 36h11 has 587 codes).
SMALL_LOOKUP = 587
#: The whole frame as a patch for ``render_scene(extra=...)``: unit square → 640×480 pixels.
_FRAME = np.array([[640.0, 0, -0.5], [0, 480.0, -0.5], [0, 0, 1]])


def photographs() -> list[tuple[str, _U8]]:
    """scikit-image's bundled photographs and textures, grey, 640×480 (area-averaged or cubic)."""
    import skimage.data

    frames: list[tuple[str, _U8]] = []
    for name in PHOTOS:
        image = np.asarray(getattr(skimage.data, name)())
        if image.ndim == 3:
            image = cv2.cvtColor(np.ascontiguousarray(image[..., :3]), cv2.COLOR_RGB2GRAY)
        if image.dtype != np.uint8:
            image = cv2.normalize(image.astype(np.float64), None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
        shrink = image.shape[0] >= 480 and image.shape[1] >= 640
        frame = cv2.resize(image, (640, 480), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_CUBIC)
        frames.append((name, np.asarray(frame, dtype=np.uint8)))
    return frames


def tag_on_wall(
    walls: Sequence[tuple[str, _U8]], tags: Sequence[scenes.DrawableTag], count: int, seed: int
) -> tuple[list[_U8], dict[str, list[_U8]]]:
    """``count`` frames of one tag drawn on a photograph, and each peer's frames of the same
    scenes (its marker at the tag's pose and size, the same degradation)."""
    rng = np.random.default_rng(seed)
    markers = {peer: marker_patch(peer) for peer in PEERS}
    ours: list[_U8] = []
    theirs: dict[str, list[_U8]] = {peer: [] for peer in PEERS}
    while len(ours) < count:
        tag = tags[int(rng.integers(len(tags)))]
        wall = walls[len(ours) % len(walls)][1]
        narrowest = max(70.0, scenes.min_width_px(tag.printed_mp_unit))
        if narrowest > 160:
            continue  # a tag of small MP must be drawn larger than the set's sizes
        width = rng.uniform(narrowest, 180)
        centre = (float(rng.uniform(200, 440)), float(rng.uniform(160, 320)))
        spec = scenes.posed_spec(tag, rng, width, rng.uniform(0, 50), center_px=centre)
        cond: dict[str, Any] = {"blur": rng.uniform(0.3, 1.0), "noise": rng.uniform(1, 4), "jpeg": 80}
        frame_seed = int(rng.integers(1 << 30))
        wall_patch = (wall, _FRAME)
        ours.append(
            scenes.render_scene((480, 640), [spec], np.random.default_rng(frame_seed), extra=[wall_patch], **cond).image
        )
        for peer, marker in markers.items():
            extra = [wall_patch, (marker, spec.homography @ PATCH_TO_DATA_AREA)]
            theirs[peer].append(
                scenes.render_scene((480, 640), [], np.random.default_rng(frame_seed), extra=extra, **cond).image
            )
    return ours, theirs


def frame_times(read: Callable[[_Frame], int], frames: Sequence[_Frame], passes: int) -> tuple[list[float], int]:
    """Each frame's best ms over ``passes`` runs, and what the last run counted."""
    best = [float("inf")] * len(frames)
    count = 0
    for _ in range(passes):
        count = 0
        for i, frame in enumerate(frames):
            t0 = time.perf_counter()
            count += read(frame)
            best[i] = min(best[i], (time.perf_counter() - t0) * 1000)
    return best, count


def stage_means(det: Detector, frames: Sequence[_U8]) -> tuple[str, str]:
    """Our ms/frame per stage (one run over the frames), the stages above 0.05 ms; and per
    candidate pass (its readings included), with the share of frames that ran it."""
    spent = dict.fromkeys(STAGES, 0.0)
    passes: dict[str, float] = {}
    runs: dict[str, int] = {}
    for frame in frames:
        report = det.detect_with_report(frame)
        for stage, seconds in report.timings:
            spent[stage] += seconds * 1000 / len(frames)
        for name, seconds in report.passes:
            passes[name] = passes.get(name, 0.0) + seconds * 1000 / len(frames)
            runs[name] = runs.get(name, 0) + 1
    per_pass = ", ".join(f"{name} {ms:.1f} ({100 * runs[name] / len(frames):.0f} %)" for name, ms in passes.items())
    return ", ".join(f"{stage} {ms:.1f}" for stage, ms in spent.items() if ms >= 0.05), per_pass


def settings_rows(lookup: MemoryLookup, photos: Sequence[_U8], aruco: list[float], passes: int) -> None:
    """Ours on the photographs with a small lookup (the first :data:`SMALL_LOOKUP` k = 8 order
    types by ID), without reading by model, without the last-resort candidate passes, and
    without either: mean and slowest ms, each against ArUco's, and the time of each candidate
    pass (one more run)."""
    small = MemoryLookup(sorted((e for e in lookup if e.k == 8), key=lambda e: e.lambda_text)[:SMALL_LOOKUP])
    # (label, detector, whether its passes' OpenCV floor is printed: where the passes differ)
    for label, det, floor in (
        (f"a lookup of {len(small)} order types", Detector(small), False),
        ("no reading by model", Detector(lookup, DetectorParams(model_match=False)), False),
        ("no last-resort passes", Detector(lookup, DetectorParams(last_resort_passes=False)), True),
        ("neither", Detector(lookup, DetectorParams(last_resort_passes=False, model_match=False)), False),
    ):
        det.detect(photos[0])
        times, count = frame_times(functools.partial(_detections, det), photos, passes)
        print(
            f"  ours, {label}: mean {np.mean(times):6.2f} ms ({np.mean(times) / np.mean(aruco):.1f}× ArUco),"
            f" slowest {max(times):6.2f} ms ({max(times) / max(aruco):.1f}× ArUco's slowest), detections: {count}"
        )
        print(f"    its candidate passes, ms/frame: {stage_means(det, photos)[1]}")
        if floor:
            opencv_floor(det, photos, aruco, passes)


def opencv_floor(det: Detector, photos: Sequence[_U8], aruco: list[float], passes: int) -> None:
    """What the candidate passes' OpenCV work alone costs on the photographs — each pass's
    threshold and contour trace (:func:`~ottag_db.decode.binarize.binarize`), no outline and no
    reading — for the passes ``det`` runs on each frame, against ArUco's whole detection: a floor
    that no faster outlining or reading lowers while the passes stay."""
    kinds = [tuple(name for name, _ in det.detect_with_report(frame).passes) for frame in photos]
    params = det.params

    def trace(index: int) -> int:
        for kind in kinds[index]:
            binarize(photos[index], cast(Binarization, kind), params)
        return 0

    times, _ = frame_times(trace, range(len(photos)), passes)
    print(
        f"    their thresholds and contour traces alone (OpenCV, {len(kinds[0])} passes on the first frame):"
        f" mean {np.mean(times):6.2f} ms ({np.mean(times) / np.mean(aruco):.1f}× ArUco's whole detection),"
        f" slowest {max(times):6.2f} ms ({max(times) / max(aruco):.1f}× ArUco's slowest)"
    )


def _detections(det: Detector, frame: _U8) -> int:
    """How many tags ``det`` reads in ``frame``."""
    return len(det.detect(frame))


def _row(label: str, times: list[float], count: int, of: str) -> None:
    print(f"  {label:<9} mean {np.mean(times):7.2f} ms   slowest {max(times):7.2f} ms   {of}: {count}")


def _ratios(ours: list[float], aruco: list[float], april: list[float]) -> str:
    """Mean ours/ArUco and ours/AprilTag, and the slowest frames' ratio to ArUco's slowest."""
    mean = float(np.mean(ours))
    return (
        f"  mean ours/ArUco {mean / np.mean(aruco):.1f}, ours/AprilTag {mean / np.mean(april):.1f};"
        f" slowest ours / slowest ArUco {max(ours) / max(aruco):.1f}"
    )


def main(tags_count: int, seed: int, passes: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        lookup, records = bundled_tags(Path(tmp))
    det = Detector(lookup)
    reader = PeerReader()
    walls = photographs()
    names = [name for name, _ in walls]
    photos = [frame for _, frame in walls]
    tags = [drawable(t) for t in records if t.k == 8]
    ours_tag, peers_tag = tag_on_wall(walls, tags, tags_count, seed)
    det.detect(photos[0])
    print(f"OpenCV threads: {cv2.getNumThreads()}; each frame's best of {passes} runs")

    print(f"photographs and textures without a tag ({len(photos)} frames, 640×480): detections (all false)")
    t_ours, n_ours = frame_times(functools.partial(_detections, det), photos, passes)
    t_aruco, n_aruco = frame_times(lambda f: len(reader.ids(PEERS[0], f)), photos, passes)
    t_april, n_april = frame_times(lambda f: len(reader.ids(PEERS[1], f)), photos, passes)
    _row("ours", t_ours, n_ours, "detections")
    _row("ArUco", t_aruco, n_aruco, "detections")
    _row("AprilTag", t_april, n_april, "detections")
    print(_ratios(t_ours, t_aruco, t_april))
    stages, per_pass = stage_means(det, photos)
    print(f"  our stages, ms/frame: {stages}")
    print(f"  our candidate passes, ms/frame (share of frames that ran it): {per_pass}")
    opencv_floor(det, photos, t_aruco, passes)
    print("  per frame, ms (ours / ArUco / AprilTag):")
    for name, a, b, c in zip(names, t_ours, t_aruco, t_april, strict=True):
        print(f"    {name:<22} {a:7.2f} {b:6.2f} {c:6.2f}")
    settings_rows(lookup, photos, t_aruco, passes)

    print(f"one tag or marker on a photograph ({tags_count} frames, seed {seed}): tags read")
    t_ours, n_ours = frame_times(lambda f: int(bool(det.detect(f))), ours_tag, passes)
    t_aruco, n_aruco = frame_times(lambda f: int(MARKER_ID in reader.ids(PEERS[0], f)), peers_tag[PEERS[0]], passes)
    t_april, n_april = frame_times(lambda f: int(MARKER_ID in reader.ids(PEERS[1], f)), peers_tag[PEERS[1]], passes)
    _row("ours", t_ours, n_ours, "read")
    _row("ArUco", t_aruco, n_aruco, "read")
    _row("AprilTag", t_april, n_april, "read")
    print(_ratios(t_ours, t_aruco, t_april))
    stages, per_pass = stage_means(det, ours_tag)
    print(f"  our stages, ms/frame: {stages}")
    print(f"  our candidate passes, ms/frame (share of frames that ran it): {per_pass}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tags", type=int, default=40, help="frames with a tag on a photograph (default 40)")
    parser.add_argument("--seed", type=int, default=1, help="draws the tags' poses (default 1)")
    parser.add_argument("--passes", type=int, default=3, help="runs per frame, the best counts (default 3)")
    args = parser.parse_args()
    if args.tags < 1 or args.passes < 1:
        parser.error("--tags and --passes must be at least 1")
    main(args.tags, args.seed, args.passes)
