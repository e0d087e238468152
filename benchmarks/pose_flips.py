"""Pose flips on small, far, nearly fronto-parallel tags: ours vs ArUco 6×6 vs AprilTag 36h11.

Usage: python benchmarks/pose_flips.py [--poses N] [--seed S] [--frames F] [--tags T] [--diagnose] [--quiet]

Still poses: a 10 cm black square (the data area, the ArUco and the AprilTag black square) at
1.0–2.5 m (about 28–70 px wide), tilted 0–30° from the optical axis about a random in-plane axis,
random roll, off the image centre, photographed by the camera of ``benchmarks/pose_accuracy.py``
(640×480, f = 700 px, no distortion) with its renderer and blur σ 0.6 px / noise σ 2 grey levels:
our tags are ``ottag-db export`` PDFs rasterized by pypdfium2 (``pose_accuracy.tag_texture``),
outside the decoder tests' drawing path; the peers are drawn by ``pose_accuracy.marker_texture``
(``cv2.aruco.generateImageMarker``, DICT_6X6_250 and DICT_APRILTAG_36h11, marker 3) with the same
black square. Each pose is rendered once per marker, with the same noise seed.

- ours: ``Detector`` on the bundled lookup, ``estimate_pose`` with the placement ``decode --json``
  uses; its ``ambiguous`` flag is counted and flips are counted among the poses it does not flag;
- ArUco: ``CORNER_REFINE_SUBPIX``, ``cv2.solvePnP(..., SOLVEPNP_IPPE_SQUARE)``
  (``pose_accuracy.peer_pose``);
- AprilTag 3: ``pupil_apriltags.Detector("tag36h11")`` with its defaults, its own pose:
  ``detect(..., estimate_tag_pose=True, camera_params, tag_size)``.

A flip is a tag-plane normal error over 10°. Printed per method: poses read, flips, mean and
median normal error (all poses read, and the poses all three read).

``--diagnose`` adds a row per still pose flagged or flipped: its size, the detection's
``corners_seen``, each corner's and the largest vertex's distance from its true image position
(px), the ambiguity and the errors of the pose and of its alternative — where the evidence is
lost (a corner measured off, a vertex at a sharp tip) rather than only how often.

Video: a camera moving past the tag (``--frames`` frames at 1.4–2.2 m, the tag 2–12° from
fronto-parallel, turning and rolling slowly); our per-frame poses go through
:class:`ottag_db.app.pose_tracking.PoseTracker` as ``decode`` does with a video; printed: frames
read, flips of the frame-alone choice and of the tracked poses, frames chosen by the track.
Issue 39's targets: no flip among the still poses not flagged, at most 2 % flagged, our median
below both peers'; no flip in the tracked video poses. The thresholds of
:mod:`ottag_db.decode.pose_ambiguity` were set on seeds 1 and 2; the default seed 3 is fresh.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from decode_speed import bundled_tags
from peers import PEERS, PeerReader
from pose_accuracy import SIZE, Texture, errors, marker_texture, peer_pose, render, tag_texture

from ottag_db.core.placement import tag_placement
from ottag_db.decode import Detection, Detector, Pose, estimate_pose, tag_object_points

K_PARAMS = (700.0, 700.0, 319.5, 239.5)
K = np.array([[700.0, 0, 319.5], [0, 700.0, 239.5], [0, 0, 1.0]])
FLIP_DEG = 10.0


@dataclass(frozen=True)
class Case:
    """One true pose: distance to the tag centre (m), tilt (°), ``X_cam = R @ X_tag + t``."""

    dist: float
    tilt: float
    r_mat: np.ndarray
    t: np.ndarray


def _pose(dist: float, tilt: float, axis: float, roll: float, off_px: tuple[float, float]) -> Case:
    """Tilt ``tilt``° about the in-plane axis at angle ``axis``, roll about the optical axis, centre at ``off_px``."""
    rx, _ = cv2.Rodrigues(np.array([math.cos(axis), math.sin(axis), 0.0]) * math.radians(tilt))
    rz, _ = cv2.Rodrigues(np.array([0.0, 0.0, math.radians(roll)]))
    r_mat = rz @ rx
    centre = np.array([off_px[0] * dist / K_PARAMS[0], off_px[1] * dist / K_PARAMS[1], dist])
    return Case(dist, tilt, r_mat, centre - r_mat @ np.array([SIZE / 2, SIZE / 2, 0.0]))


def still_cases(n: int, seed: int) -> list[Case]:
    """``n`` random poses: 1.0–2.5 m, tilt 0–30°, random tilt axis and roll, centre within ±200 × ±140 px."""
    rng = np.random.default_rng(seed)
    return [
        _pose(
            float(rng.uniform(1.0, 2.5)),
            float(rng.uniform(0.0, 30.0)),
            float(rng.uniform(0, 2 * math.pi)),
            float(rng.uniform(0, 360)),
            (float(rng.uniform(-200, 200)), float(rng.uniform(-140, 140))),
        )
        for _ in range(n)
    ]


def video_cases(n: int) -> list[Case]:
    """A camera gliding past the tag: 1.4–2.2 m, 2–12° from fronto-parallel, slowly turning and rolling."""
    out = []
    for i in range(n):
        s = i / max(n - 1, 1)
        tilt = 7.0 + 5.0 * math.sin(2 * math.pi * 1.5 * s)
        axis = 0.6 + 2.5 * s
        off = (-150 + 300 * s, 60 * math.sin(2 * math.pi * s))
        out.append(_pose(1.4 + 0.8 * s, tilt, axis, 15.0 * math.sin(2 * math.pi * s), off))
    return out


def apriltag_pose(detector: Any, img: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """AprilTag 3's own pose (``estimate_tag_pose``) of marker 3 in our tag frame (its frame:
    centre origin, x right, y down, z into the tag)."""
    found = [d for d in detector.detect(img, True, K_PARAMS, SIZE) if d.tag_id == 3]
    if not found:
        return None
    r_mat = np.asarray(found[0].pose_R, dtype=np.float64)
    t = np.asarray(found[0].pose_t, dtype=np.float64).ravel()
    return r_mat, t - r_mat @ np.array([SIZE / 2, SIZE / 2, 0.0])


@dataclass
class Setup:
    """Textures, detectors and tags of one run."""

    tags: list[Any]
    textures: list[Texture]
    detector: Detector
    aruco: Texture
    april: Texture
    peers: PeerReader
    april_detector: Any


def make_setup(n_tags: int) -> Setup:
    """Export and rasterize ``n_tags`` k = 8 tags (the most printable), build the detectors."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        lookup, records = bundled_tags(folder)
        good = sorted((t for t in records if t.k == 8 and t.unique_min), key=lambda t: -t.printed_mp_unit)
        tags = good[:n_tags]
        textures = [tag_texture(folder / "bundled.sqlite", t, folder) for t in tags]
    from pupil_apriltags import Detector as AprilTagDetector

    peers = PeerReader()  # ArUco with sub-pixel corners (what a pose needs)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    peers.aruco.setDetectorParameters(params)
    april = AprilTagDetector("tag36h11")  # its defaults; its own pose
    return Setup(tags, textures, Detector(lookup), marker_texture(PEERS[0]), marker_texture(PEERS[1]), peers, april)


def our_detection(setup: Setup, i: int, case: Case, seed: int) -> Detection | None:
    """Our tag ``i % len(tags)`` photographed at ``case`` and decoded (None when not read)."""
    tag, tex = setup.tags[i % len(setup.tags)], setup.textures[i % len(setup.tags)]
    img = render(tex, case.r_mat, case.t, seed)
    found = [d for d in setup.detector.detect(img) if d.lambda_text == tag.lambda_text]
    return found[0] if found else None


def our_pose(d: Detection) -> Pose:
    """``estimate_pose`` as ``decode --json`` calls it."""
    placement = None if d.model_points is None else tag_placement(d.model_points)
    return estimate_pose(d, K, None, SIZE, placement)


@dataclass(frozen=True)
class StillRow:
    """One still pose: the case, our detection (None: not read), the peers' errors (None: not read)."""

    case: Case
    ours: Detection | None
    aruco: tuple[float, float] | None
    april: tuple[float, float] | None


def still_rows(setup: Setup, cases: list[Case], seed: int, quiet: bool) -> list[StillRow]:
    """Render and read every case for the three markers (the same noise seed per pose)."""
    rows = []
    for i, case in enumerate(cases):
        if not quiet:
            print(f"\rpose {i + 1}/{len(cases)}", end="", file=sys.stderr, flush=True)
        noise = 1000 * seed + 1000 + i
        d = our_detection(setup, i, case, noise)
        ap = peer_pose(setup.peers, PEERS[0], render(setup.aruco, case.r_mat, case.t, noise))
        tp = apriltag_pose(setup.april_detector, render(setup.april, case.r_mat, case.t, noise))
        rows.append(
            StillRow(
                case,
                d,
                None if ap is None else errors(ap[0], ap[1], case.r_mat, case.t),
                None if tp is None else errors(tp[0], tp[1], case.r_mat, case.t),
            )
        )
    if not quiet:
        print(file=sys.stderr)
    return rows


def _stats(errs: list[float]) -> str:
    a = np.array(errs) if errs else np.array([np.nan])
    return f"{int(np.sum(a > FLIP_DEG)):6d} {np.mean(a):8.3f} {np.median(a):8.3f}"


def report_still(rows: list[StillRow]) -> None:
    """Print flips and normal errors side by side (all poses read, and the poses all three read)."""
    ours: list[tuple[float, bool] | None] = []
    for r in rows:
        if r.ours is None:
            ours.append(None)
            continue
        p = our_pose(r.ours)
        ours.append((errors(p.R, p.tvec, r.case.r_mat, r.case.t)[0], p.ambiguous))
    n = len(rows)
    read = [o for o in ours if o is not None]
    flagged = sum(o[1] for o in read)
    both = [i for i, r in enumerate(rows) if ours[i] is not None and r.aruco is not None and r.april is not None]
    print(f"{'':26} {'read':>8} {'flips':>6} {'mean °':>8} {'median °':>8} | on the {len(both)} poses all three read")
    table = (
        ("ours (estimate_pose)", [o[0] if o else None for o in ours]),
        ("ArUco 6×6 IPPE_SQUARE", [r.aruco[0] if r.aruco else None for r in rows]),
        ("AprilTag 3 (pupil)", [r.april[0] if r.april else None for r in rows]),
    )
    for name, errs in table:
        got = [e for e in errs if e is not None]
        common = [e for i, e in enumerate(errs) if i in both and e is not None]
        print(f"{name:26} {len(got):4d}/{n:<3d} {_stats(got)} | {_stats(common)}")
    clear = [o[0] for o in read if not o[1]]
    print(
        f"ours: {flagged} of {len(read)} poses flagged ambiguous ({100 * flagged / max(len(read), 1):.1f} %); "
        f"flips among the others: {sum(e > FLIP_DEG for e in clear)}; "
        f"flips among the flagged: {sum(o[0] > FLIP_DEG for o in read if o[1])}"
    )


def report_diagnosis(rows: list[StillRow]) -> None:
    """One row per still pose flagged ambiguous or flipped: what the detection measured wrong."""
    print("flagged or flipped (px: distance of each corner / the worst vertex from its true image position):")
    for i, r in enumerate(rows):
        if r.ours is None:
            continue
        p = our_pose(r.ours)
        err = errors(p.R, p.tvec, r.case.r_mat, r.case.t)[0]
        if not (p.ambiguous or err > FLIP_DEG):
            continue
        placement = None if r.ours.model_points is None else tag_placement(r.ours.model_points)
        obj, img = tag_object_points(r.ours, SIZE, placement)
        true_img, _ = cv2.projectPoints(obj, cv2.Rodrigues(r.case.r_mat)[0], r.case.t, K, None)
        off = np.linalg.norm(img - true_img.reshape(-1, 2), axis=1)
        side = float(np.mean(np.linalg.norm(np.roll(r.ours.corners, -1, axis=0) - r.ours.corners, axis=1)))
        seen = "".join("s" if s else "-" for s in (r.ours.corners_seen or (True,) * 4))
        alt = errors(np.asarray(cv2.Rodrigues(p.alternative.rvec)[0]), p.alternative.tvec, r.case.r_mat, r.case.t)[0]
        print(
            f"  #{i:<3d} {r.case.dist:.2f} m tilt {r.case.tilt:4.1f}° side {side:4.1f} px seen {seen} "
            f"corners {' '.join(f'{v:.2f}' for v in off[:4])} vertex max {off[4:].max(initial=0.0):.2f} | "
            f"ambiguity {p.ambiguity:.3f}{' flagged' if p.ambiguous else ''}, error {err:.1f}° (alternative {alt:.1f}°)"
        )


def report_video(setup: Setup, frames: int, seed: int) -> None:
    """Our poses on the moving-camera sequence, frame alone and through the tracker."""
    from ottag_db.app.pose_tracking import PoseTracker

    tracker = PoseTracker()
    alone, tracked, by_track, flagged, read = [], [], 0, 0, 0
    for i, case in enumerate(video_cases(frames)):
        d = our_detection(setup, 0, case, 1000 * seed + 500_000 + i)
        if d is None:
            continue
        read += 1
        p = our_pose(d)
        t = tracker.choose(d.lambda_text, i, p)
        alone.append(errors(p.R, p.tvec, case.r_mat, case.t)[0])
        tracked.append(errors(t.pose.R, t.pose.tvec, case.r_mat, case.t)[0])
        by_track += t.chosen_by == "previous_frames"
        flagged += p.ambiguous
    print(
        f"video: {frames} frames, camera gliding past the tag at 1.4–2.2 m, 2–12° from fronto-parallel; "
        f"{read} read, {flagged} flagged ambiguous, {by_track} chosen by the previous frames"
    )
    print(f"{'':26} {'flips':>6} {'mean °':>8} {'median °':>8}")
    print(f"{'frame alone':26} {_stats(alone)}")
    print(f"{'through PoseTracker':26} {_stats(tracked)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=240, help="still poses [240]")
    parser.add_argument("--frames", type=int, default=150, help="video frames [150]")
    parser.add_argument("--tags", type=int, default=3, help="k = 8 tags cycled over the poses [3]")
    parser.add_argument("--seed", type=int, default=3, help="poses and noise seed (tuned on 1 and 2) [3]")
    parser.add_argument("--diagnose", action="store_true", help="a row per still pose flagged or flipped")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    args = parser.parse_args()
    setup = make_setup(args.tags)
    rows = still_rows(setup, still_cases(args.poses, args.seed), args.seed, args.quiet)
    print(
        f"{args.poses} poses (seed {args.seed}), 640×480, f = 700 px, 10 cm black square at 1.0–2.5 m, "
        f"tilt 0–30°, random roll; blur σ 0.6 px, noise σ 2; flip = normal error > {FLIP_DEG:.0f}°"
    )
    report_still(rows)
    if args.diagnose:
        report_diagnosis(rows)
    report_video(setup, args.frames, args.seed)
    # pupil_apriltags' detector, after estimate_tag_pose, now and then aborts when it is freed
    # ("corrupted size vs. prev_size", pupil-labs/apriltags issue 39): leave without freeing it
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
