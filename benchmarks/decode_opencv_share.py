"""OpenCV's share of our decoder's time, beside ArUco's and AprilTag's whole detection.

Usage: python benchmarks/decode_opencv_share.py [--frames N] [--passes P] [--params KEY=VALUE ...]

Our stages call OpenCV through its Python bindings: the candidate passes' thresholds and contour
traces, the data areas' hulls, histograms, distance transforms and remaps, the model's ECC
alignments and warps. This benchmark times every one of those calls — each function of the
``cv2`` module is wrapped while it measures, the wrapper's own overhead subtracted — on three
sets of frames, and sets that time beside ArUco's (``cv2.aruco.ArucoDetector``, OpenCV's default
threads) and AprilTag 3's (``pupil_apriltags``, defaults) whole detection on the same scenes, in
the same run:

- *one tag*: the frames of ``decode_speed.py`` (640×480, one tag or marker);
- *20 tags*: the boards of ``decode_many.py`` (1280×960);
- *photographs*: scikit-image's photographs and textures of ``decode_photos.py`` (no tag).

While the stages make these calls, no faster code of ours between them brings a frame under
their time: it is a floor of the current design. The decoder design's targets (issue 37) are
≤ 1.0 × ArUco's mean on one tag, ≤ 1.5 × on 20 tags and on the photographs. Prints per set the
mean ms per frame (best of ``--passes`` interleaved runs) of ours, of ArUco and of AprilTag, our
OpenCV calls per frame and their time, the rest of ours, the ratios to ArUco, and the OpenCV
functions that take most of it. ``--params`` reads with other settings of our decoder
(``settings.py``; e.g. ``last_resort_passes=false``, ``decode --fast``). Needs
``pip install '.[bench]'`` (scikit-image, pupil-apriltags).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode import Detector, DetectorParams

sys.path.insert(0, str(Path(__file__).resolve().parent))
from decode_many import make_frames  # the benchmarks next door
from decode_photos import photographs
from decode_speed import make_scenes
from peers import PEERS, PeerReader
from settings import add_params_argument, describe, params_from

_U8 = NDArray[np.uint8]
#: The issue's targets: our mean time over ArUco's, per set.
TARGETS = {"one tag": 1.0, "20 tags": 1.5, "photographs": 1.5}
#: OpenCV functions listed per set (the largest shares of its OpenCV time).
TOP_FUNCTIONS = 6


@dataclass
class OpenCVClock:
    """Seconds and calls per ``cv2`` function while :func:`timed_opencv` is active."""

    seconds: defaultdict[str, float]
    calls: Counter[str]
    overhead: float  # seconds the wrapper adds to one call (subtracted)

    def total(self) -> tuple[float, int]:
        """Seconds in OpenCV (the wrappers' overhead subtracted) and the number of calls."""
        count = sum(self.calls.values())
        return max(sum(self.seconds.values()) - count * self.overhead, 0.0), count


def _wrapped(name: str, function: Callable[..., Any], clock: OpenCVClock) -> Callable[..., Any]:
    def timed(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            clock.seconds[name] += time.perf_counter() - start
            clock.calls[name] += 1

    return timed


@contextmanager
def timed_opencv() -> Iterator[OpenCVClock]:
    """Time every call into the ``cv2`` module's functions while the block runs.

    Our modules call OpenCV as ``cv2.name(...)``, so replacing the module's functions for the
    block sees all of them (classes, such as ``cv2.error``, stay as they are); they are restored
    when the block ends.

    Yields
    ------
    OpenCVClock
        Filled while the block runs.
    """
    names = [
        n for n in dir(cv2)
        if n[:1].islower() and callable(getattr(cv2, n)) and not isinstance(getattr(cv2, n), type)
    ]  # fmt: skip
    originals = {n: getattr(cv2, n) for n in names}
    clock = OpenCVClock(defaultdict(float), Counter(), 0.0)
    probe = _wrapped("probe", lambda: None, clock)
    rounds = 20_000
    start = time.perf_counter()
    for _ in range(rounds):
        probe()
    clock.overhead = (time.perf_counter() - start) / rounds
    clock.seconds.clear()
    clock.calls.clear()
    try:
        for n in names:
            setattr(cv2, n, _wrapped(n, originals[n], clock))
        yield clock
    finally:
        for n, function in originals.items():
            setattr(cv2, n, function)


@dataclass(frozen=True)
class FrameSet:
    """One set: our frames, and each peer's frames of the same scenes (the photographs: the same)."""

    name: str
    ours: list[_U8]
    peers: dict[str, list[_U8]]
    detector: Detector


def frame_sets(frames: int, params: DetectorParams) -> list[FrameSet]:
    """The three sets, each with a detector of its benchmark's lookup and ``params``."""
    # (the one-tag frames and the photographs are read with the same lookup, decode_photos.py's)
    lookup, ours, peer_frames = make_scenes(frames)
    bundled = Detector(lookup, params)
    boards = max(1, math.ceil(frames / 25))  # 20 tags a frame: a few boards
    board_lookup, scenes, board_frames, _ = make_frames(boards)
    photos = [frame for _, frame in photographs()]
    return [
        FrameSet("one tag", ours, peer_frames, bundled),
        FrameSet("20 tags", [s.image for s in scenes], board_frames, Detector(board_lookup, params)),
        FrameSet("photographs", photos, dict.fromkeys(PEERS, photos), bundled),
    ]


def _mean_ms(run: Callable[[_U8], object], frames: Sequence[_U8]) -> float:
    start = time.perf_counter()
    for frame in frames:
        run(frame)
    return (time.perf_counter() - start) / len(frames) * 1000


def _peer_run(reader: PeerReader, peer: str) -> Callable[[_U8], object]:
    return lambda frame: reader.ids(peer, frame)


def measure(frame_set: FrameSet, reader: PeerReader, passes: int) -> None:
    """Print the set's times: ours, our OpenCV calls, the rest, ArUco, AprilTag."""
    det = frame_set.detector
    runs: dict[str, Callable[[_U8], object]] = {"ours": det.detect}
    runs.update({peer: _peer_run(reader, peer) for peer in PEERS})
    inputs = {"ours": frame_set.ours, **frame_set.peers}
    for name, run in runs.items():  # warm
        _mean_ms(run, inputs[name][:3])
    best = dict.fromkeys(runs, math.inf)
    for _ in range(passes):  # interleaved, best of several: other processes share the cores
        for name, run in runs.items():
            best[name] = min(best[name], _mean_ms(run, inputs[name]))
    inside = math.inf
    per_call: dict[str, float] = {}
    calls = 0
    for _ in range(passes):
        with timed_opencv() as clock:
            _mean_ms(det.detect, frame_set.ours)
        seconds, count = clock.total()
        if seconds < inside:
            inside, calls = seconds, count
            per_call = {n: s - clock.calls[n] * clock.overhead for n, s in clock.seconds.items()}
    n = len(frame_set.ours)
    inside_ms = inside / n * 1000
    aruco, april, ours = best[PEERS[0]], best[PEERS[1]], best["ours"]
    target = TARGETS[frame_set.name]
    print(f"{frame_set.name} ({n} frames of {frame_set.ours[0].shape[1]}×{frame_set.ours[0].shape[0]})")
    print(f"  ours      {ours:7.2f} ms/frame   {ours / aruco:5.1f}× ArUco   (target ≤ {target:.1f}×)")
    print(
        f"    its OpenCV calls alone {inside_ms:7.2f} ms/frame   {inside_ms / aruco:5.1f}× ArUco's whole detection"
        f"   ({calls / n:.0f} calls a frame)"
    )
    print(f"    the rest (our own code) {max(ours - inside_ms, 0.0):6.2f} ms/frame")
    print(f"  ArUco     {aruco:7.2f} ms/frame")
    print(f"  AprilTag  {april:7.2f} ms/frame   ours {ours / april:.1f}× AprilTag's")
    largest = sorted(per_call.items(), key=lambda item: -item[1])[:TOP_FUNCTIONS]
    top = ", ".join(f"{name} {s / n * 1000:.2f}" for name, s in largest)
    print(f"    largest OpenCV shares, ms/frame: {top}")


def main(frames: int, passes: int, params: DetectorParams) -> None:
    print(f"OpenCV threads: {cv2.getNumThreads()}; best of {passes} interleaved runs; our settings: {describe(params)}")
    reader = PeerReader()
    for frame_set in frame_sets(frames, params):
        measure(frame_set, reader, passes)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=100, help="one-tag frames (default 100; a board per 25)")
    parser.add_argument("--passes", type=int, default=3, help="interleaved runs, the best counted (default 3)")
    add_params_argument(parser)
    args = parser.parse_args()
    if args.frames < 1 or args.passes < 1:
        parser.error("--frames and --passes must be at least 1")
    main(args.frames, args.passes, params_from(args.params, parser))
