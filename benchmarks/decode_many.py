"""Many tags per frame: 20 Order Type Tags of a D = 2 dictionary vs 20 ArUco and 20 AprilTag markers, one board.

Usage: python benchmarks/decode_many.py [frames] [cv2_threads] [--plot PATH]

Each frame (1280×960, f = 1400 px) shows a board of 5 × 4 cells seen under a random
perspective (tilt 0–40° about a random axis, any roll): once with 20 Order Type Tags (k = 8, the
20 of highest MP whose pairwise flip distance is at least 2, i.e. no two differ in a single
triple orientation), once each with 20 ArUco 6×6 and 20 AprilTag 36h11 markers (ids 0–19,
``peers.py``) whose black squares cover exactly the same data areas; the same blur, noise, light
gradient and JPEG 80. The decoder looks up every
order type of k = 5 … 8 (mirrors included), so a misread could land on any of them.
Prints per frame the tags decoded (target 20/20) and the wrong IDs (must be 0), then ms/frame of
the detectors (best of several interleaved passes) with OpenCV's default thread count and with one
(AprilTag 3: one thread, its default). ``--plot PATH`` writes the times as bars (PNG, matplotlib).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.flips import flip_neighbours
from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import Detection, Detector
from ottag_db.printing import scenes
from ottag_db.printing.camera import camera_matrix, project

sys.path.insert(0, str(Path(__file__).resolve().parent))
from decode_speed import bundled_tags, drawable  # the benchmark next door
from peers import PEERS, PeerReader, aruco_dictionary, plot_bars

#: Board of COLS × ROWS cells; a cell is PITCH data-area sides wide (quiet zone 0.25 on each
#: side of the data area, 0.1 between neighbouring quiet zones).
COLS, ROWS, PITCH = 5, 4, 1.6
SHAPE = (960, 1280)
FOCAL = 1400.0
N_TAGS = COLS * ROWS
#: Pixels per data-area side of the ArUco board patch.
PATCH_PX = 120


def pick_dictionary(tags: Sequence[scenes.DrawableTag], n: int, pool: int = 300) -> list[scenes.DrawableTag]:
    """The ``n`` tags of highest MP, taken greedily, no two of them flip neighbours.

    Parameters
    ----------
    tags : sequence of DrawableTag
        Tags of one k (points in canonical label order).
    n : int
        Tags wanted.
    pool : int
        Only the ``pool`` tags of highest MP are considered (their flip edges among each
        other are all a pairwise-distance check needs).

    Returns
    -------
    list of DrawableTag
        Pairwise flip distance ≥ 2, MP descending.
    """
    cand = sorted(tags, key=lambda t: (-t.printed_mp_unit, t.lambda_text))[:pool]
    edges = flip_neighbours(np.stack([t.points for t in cand]), [t.lambda_text for t in cand])
    adj: dict[int, set[int]] = {}
    for e in edges:
        adj.setdefault(e.source, set()).add(e.target)
        adj.setdefault(e.target, set()).add(e.source)
    chosen: list[int] = []
    for i in range(len(cand)):
        if not adj.get(i, set()) & set(chosen):
            chosen.append(i)
        if len(chosen) == n:
            break
    return [cand[i] for i in chosen]


def board_homography(rng: np.random.Generator) -> NDArray[np.float64]:
    """Board plane (units: data-area sides, origin at the board's top-left) → image pixels.

    The board is tilted by 0–40° about a random axis in its plane and rolled by up to ±25°,
    then moved along the optical axis and sideways until its outline fills 80–92 % of the
    frame in its tighter direction, centred.
    """
    h, w = SHAPE
    k_mat = camera_matrix(FOCAL, w, h)
    bw, bh = COLS * PITCH, ROWS * PITCH
    roll = math.radians(rng.uniform(-25, 25))
    axis_ang = rng.uniform(0, math.pi)
    tilt = math.radians(rng.uniform(0, 40))
    axis = np.array([math.cos(axis_ang), math.sin(axis_ang), 0.0])
    r_tilt, _ = cv2.Rodrigues(axis * tilt)
    c, s = math.cos(roll), math.sin(roll)
    r_mat = r_tilt @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    fill = rng.uniform(0.80, 0.92)
    centre = r_mat @ np.array([bw / 2, bh / 2, 0.0])
    pos = np.array([0.0, 0.0, FOCAL * bw / (0.8 * w)])  # board centre in camera coordinates
    outline = np.array([[0, 0], [bw, 0], [bw, bh], [0, bh]], dtype=np.float64)
    hom = np.eye(3)
    for _ in range(6):
        hom = k_mat @ np.column_stack([r_mat[:, 0], r_mat[:, 1], pos - centre])
        box = project(hom, outline)
        lo, hi = box.min(axis=0), box.max(axis=0)
        grow = max((hi[0] - lo[0]) / (fill * w), (hi[1] - lo[1]) / (fill * h))
        off = 0.5 * (lo + hi) - np.array([w / 2, h / 2])
        pos[:2] -= off * pos[2] / FOCAL
        pos[2] *= grow
    out: NDArray[np.float64] = hom / hom[2, 2]
    return out


def cell_homography(board: NDArray[np.float64], index: int) -> NDArray[np.float64]:
    """Data-area unit square of cell ``index`` (row-major) → image pixels."""
    r, c = divmod(index, COLS)
    off = (PITCH - 1) / 2
    out: NDArray[np.float64] = board @ np.array([[1, 0, c * PITCH + off], [0, 1, r * PITCH + off], [0, 0, 1.0]])
    return out


def marker_board(peer: str) -> NDArray[np.uint8]:
    """A peer's board as one grey patch: background 200, each marker (ids 0–19) on a white
    square of 1.5 data-area sides, its black square exactly the cell's data area."""
    dictionary = aruco_dictionary(peer)
    px = PATCH_PX
    patch = np.full((round(ROWS * PITCH * px), round(COLS * PITCH * px)), 200, dtype=np.uint8)
    for i in range(N_TAGS):
        r, c = divmod(i, COLS)
        x0 = round((c * PITCH + (PITCH - 1.5) / 2) * px)
        y0 = round((r * PITCH + (PITCH - 1.5) / 2) * px)
        q = px // 4
        marker = cv2.aruco.generateImageMarker(dictionary, i, px)
        patch[y0 : y0 + px + 2 * q, x0 : x0 + px + 2 * q] = cv2.copyMakeBorder(
            marker, q, q, q, q, cv2.BORDER_CONSTANT, value=255
        )
    return patch


def make_frames(
    frames: int, seed: int = 13
) -> tuple[MemoryLookup, list[scenes.Scene], dict[str, list[NDArray[np.uint8]]], list[scenes.DrawableTag]]:
    """Lookup, the Order Type Tag scenes, each peer's frames of the same boards and the dictionary drawn."""
    with tempfile.TemporaryDirectory() as tmp:
        lookup, records = bundled_tags(Path(tmp))
    members = pick_dictionary([drawable(t) for t in records if t.k == 8], N_TAGS)
    patches = {peer: marker_board(peer) for peer in PEERS}
    bw, bh = COLS * PITCH, ROWS * PITCH
    rng = np.random.default_rng(seed)
    ours: list[scenes.Scene] = []
    peer_frames: dict[str, list[NDArray[np.uint8]]] = {peer: [] for peer in PEERS}
    for _ in range(frames):
        board = board_homography(rng)
        order = rng.permutation(N_TAGS)  # which member sits in which cell
        specs = [
            scenes.TagSpec(
                members[m].points, members[m].triangles, cell_homography(board, i), "normal",
                lambda_text=members[m].lambda_text, placement=members[m].placement,
            )
            for i, m in enumerate(order.tolist())
        ]  # fmt: skip
        cond: dict[str, Any] = {
            "blur": rng.uniform(0, 1),
            "noise": rng.uniform(0, 4),
            "gradient": rng.uniform(0, 0.4),
            "jpeg": 80,
        }
        seed_f = int(rng.integers(1 << 30))
        ours.append(scenes.render_scene(SHAPE, specs, np.random.default_rng(seed_f), **cond))
        patch_h = board @ np.diag([bw, bh, 1.0])
        for peer, patch in patches.items():
            peer_frames[peer].append(
                scenes.render_scene(SHAPE, [], np.random.default_rng(seed_f), extra=[(patch, patch_h)], **cond).image
            )
    return lookup, ours, peer_frames, members


def score(scene: scenes.Scene, dets: Sequence[Detection]) -> tuple[int, int]:
    """Tags read right and wrong IDs (a detection on a tag with another ID, or on no tag)."""
    right = wrong = 0
    used: set[int] = set()
    for spec, truth in zip(scene.tags, scene.truth_points, strict=True):
        centre = project(spec.homography, np.array([[0.5, 0.5]]))[0]
        side = math.sqrt(abs(cv2.contourArea(project(spec.homography, _UNIT).astype(np.float32))))
        near = [i for i, d in enumerate(dets) if np.linalg.norm(d.corners.mean(axis=0) - centre) < 0.3 * side]
        used.update(near)
        right += any(dets[i].lambda_text == spec.lambda_text for i in near)
        wrong += sum(dets[i].lambda_text != spec.lambda_text for i in near)
        del truth
    return right, wrong + len(dets) - len(used)


_UNIT = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])


def _timed(run: Callable[[], int], frames: int) -> float:
    t0 = time.perf_counter()
    run()
    return (time.perf_counter() - t0) / frames * 1000


def main(frames: int = 4, passes: int = 3, plot: str | None = None) -> None:
    lookup, ours, peer_frames, members = make_frames(frames)
    det = Detector(lookup)
    reader = PeerReader()
    mps = [m.printed_mp_unit for m in members]
    print(
        f"frames: {frames} (1280×960, f = {FOCAL:.0f} px, board {COLS}×{ROWS}, tilt ≤ 40°, blur/noise/light/JPEG 80); "
        f"{N_TAGS} k = 8 tags, pairwise flip distance ≥ 2, printed MP {min(mps):.4f}–{max(mps):.4f} of the side"
    )
    total_right = total_wrong = 0
    total_peers = dict.fromkeys(PEERS, 0)
    for f, scene in enumerate(ours):
        dets = det.detect(scene.image)
        right, wrong = score(scene, dets)
        found = {peer: len(reader.ids(peer, peer_frames[peer][f]) & set(range(N_TAGS))) for peer in PEERS}
        sides = [math.sqrt(abs(cv2.contourArea(project(s.homography, _UNIT).astype(np.float32)))) for s in scene.tags]
        print(
            f"frame {f}: ours {right}/{N_TAGS} decoded, {wrong} wrong IDs; "
            + "; ".join(f"{peer} {n}/{N_TAGS}" for peer, n in found.items())
            + "; "
            f"data-area side {min(sides):.0f}–{max(sides):.0f} px"
        )
        total_right += right
        total_wrong += wrong
        for peer in PEERS:
            total_peers[peer] += found[peer]
    print(
        f"all frames: ours {total_right}/{N_TAGS * frames}, wrong IDs {total_wrong}; "
        + "; ".join(f"{peer} {n}/{N_TAGS * frames}" for peer, n in total_peers.items())
    )

    imgs = [s.image for s in ours]

    def run_ours() -> int:
        return sum(len(det.detect(im)) for im in imgs)

    def run_peer(peer: str) -> Callable[[], int]:
        return lambda: sum(len(reader.ids(peer, im)) for im in peer_frames[peer])

    runs: dict[str, Callable[[], int]] = {"Order Type Tag": run_ours, **{peer: run_peer(peer) for peer in PEERS}}
    for run in runs.values():
        run()
    threads = cv2.getNumThreads()
    times: dict[str, dict[str, float]] = {}
    for n in (threads, 1) if threads > 1 else (threads,):
        cv2.setNumThreads(n)
        best = dict.fromkeys(runs, math.inf)
        for _ in range(passes):  # interleaved, best of several: other processes share the cores
            for name, run in runs.items():
                best[name] = min(best[name], _timed(run, frames))
        times[f"OpenCV threads: {n}"] = best
        print(f"OpenCV threads: {n}")
        for name, ms in best.items():
            print(f"  {name:<15}: {ms:7.2f} ms/frame")
        ours_ms = best["Order Type Tag"]
        print("  ratio " + ", ".join(f"ours/{peer}: {ours_ms / best[peer]:.2f}" for peer in PEERS))
    cv2.setNumThreads(threads)
    if plot:
        plot_bars(plot, f"time per 1280×960 frame with {N_TAGS} tags or markers", "ms / frame", times)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("frames", type=int, nargs="?", default=4, help="frames (default 4)")
    parser.add_argument("cv2_threads", type=int, nargs="?", default=None, help="OpenCV's default thread count")
    parser.add_argument("--plot", default=None, metavar="PATH", help="write the times as bars (PNG, matplotlib)")
    args = parser.parse_args()
    if args.frames < 1:
        parser.error("frames must be at least 1")
    if args.cv2_threads is not None:
        cv2.setNumThreads(args.cv2_threads)
    main(args.frames, plot=args.plot)
