"""Hidden border: tags partly covered, or cut by the image edge — ours beside ArUco and AprilTag 3.

Usage: python benchmarks/decode_occlusion.py [--poses N] [--seed S] [--save DIR] [--params KEY=VALUE ...]

The same poses (640×480, f = 700 px; data area 110–170 px wide as a 21 cm tag at 70–110 cm,
tilt 0–45°, camera blur σ 0.5–0.9 px, noise, JPEG 85) are drawn with one 8-point tag (normal
and inverted), an ArUco 6×6 marker and an AprilTag 36h11 tag of the same size (the black
square the size of our data area), each hidden the same way (the occluder drawn in data-area
units through the same homography):

- *bar*: a finger-like bar of a random grey, 6 % of the side wide, across the middle of one
  side, from beyond the quiet zone to 6 % into the data area;
- *covered corner*: one corner covered by a grey square reaching 6 % into the data area;
- *cut corner*: the frame shifted so that one corner lies 4–7 % of the side outside it;
- *corner at the edge*: shifted so that one corner lies within 2 % of the side of the frame's
  edge, just inside or just outside it (a tag that touches the edge of the picture).

Prints per case and polarity: read (the tag's own ID), wrong IDs, and for ours the largest
corner error of the reads, in % of the data area's side (the issue's target: within 2 %). Needs
``pip install '.[bench]'`` (pupil-apriltags).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.core.types import QUIET_ZONE, Polarity
from ottag_db.decode import DEFAULT_PARAMS, Detector, DetectorParams
from ottag_db.printing import scenes

sys.path.insert(0, str(Path(__file__).resolve().parent))
from decode_speed import bundled_tags, drawable  # the benchmarks next door
from peers import MARKER_ID, PATCH_TO_DATA_AREA, PEERS, PeerReader, marker_patch
from settings import add_params_argument, describe, params_from

CASES = ("bar", "covered corner", "cut corner", "corner at edge")
#: How far one corner lies outside the frame, of the side, per case that shifts the frame
#: (negative: inside).
_CUT_DEPTH = {"cut corner": (0.04, 0.07), "corner at edge": (-0.02, 0.02)}
_F64 = NDArray[np.float64]
_U8 = NDArray[np.uint8]
_UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
_INTO = 0.06  # how far an occluder reaches into the data area (of its side)


def _occluder(case: str, rng: np.random.Generator) -> _F64 | None:
    """The occluder's polygon in data-area units (None: the case cuts the frame instead)."""
    if case in _CUT_DEPTH:
        return None
    out = 1 + QUIET_ZONE + 0.3  # beyond the quiet zone
    if case == "bar":
        half = 0.03
        poly = np.array([[0.5 - half, -out], [0.5 + half, -out], [0.5 + half, _INTO], [0.5 - half, _INTO]])
    else:
        poly = np.array([[-out, -out], [_INTO, -out], [_INTO, _INTO], [-out, _INTO]])
    turns = int(rng.integers(4))  # which side or corner
    centred = poly - 0.5
    for _ in range(turns):
        centred = centred @ np.array([[0.0, 1.0], [-1.0, 0.0]])
    return centred + 0.5


def _cut_shift(hom: _F64, rng: np.random.Generator, depths: tuple[float, float] = (0.04, 0.07)) -> _F64 | None:
    """A shift of the image that puts one data-area corner ``depths`` (of the side; 4–7 %)
    outside the frame and the other three inside: towards the frame edge where one corner
    stands out most from the others. None when no corner stands out that far (a tag square to
    the frame's axes)."""
    corners = scenes.project(hom, _UNIT)
    side = float(np.sqrt(abs(cv2.contourArea(corners.astype(np.float32)))))
    depth = rng.uniform(*depths) * side
    best: tuple[float, _F64] | None = None
    for axis, sign, limit in ((0, -1, 0.0), (0, 1, 639.0), (1, -1, 0.0), (1, 1, 479.0)):
        along = np.sort(sign * corners[:, axis])  # the last one stands out most towards that edge
        gap = float(along[3] - along[2])
        if gap > abs(depth) + 3 and (best is None or gap > best[0]):
            shift = np.zeros(2)
            shift[axis] = limit + sign * depth - sign * along[3]
            best = (gap, np.array([[1.0, 0, shift[0]], [0, 1, shift[1]], [0, 0, 1]]))
    return None if best is None else best[1]


def _degrade(image: _U8, blur: float, noise: float, rng: np.random.Generator) -> _U8:
    """Camera blur, noise and JPEG 85 (the same for every marker of a pose)."""
    img = cv2.GaussianBlur(image.astype(np.float32), (0, 0), blur) + rng.normal(0, noise, image.shape)
    ok, buf = cv2.imencode(".jpg", np.clip(img + 0.5, 0, 255).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 85])
    assert ok
    return np.asarray(cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE), dtype=np.uint8)


def _hide(image: _U8, hom: _F64, poly: _F64 | None, grey: int) -> _U8:
    """The image with the occluder drawn over it (anti-aliased)."""
    if poly is None:
        return image
    out = image.copy()
    pts = np.round(scenes.project(hom, poly) * 16).astype(np.int32)
    cv2.fillPoly(out, [pts], int(grey), lineType=cv2.LINE_AA, shift=4)
    return out


def main(poses: int, seed: int, save: str | None = None, params: DetectorParams = DEFAULT_PARAMS) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        lookup, records = bundled_tags(Path(tmp))
    det = Detector(lookup, params)
    reader = PeerReader()
    tags = [drawable(t) for t in records if t.k == 8 and scenes.min_width_px(t.printed_mp_unit) <= 100]
    markers = {peer: marker_patch(peer) for peer in PEERS}
    rng = np.random.default_rng(seed)
    print(f"{poses} poses per case (seed {seed}); read / wrong IDs; ours: largest corner error of the reads")
    print(f"our settings: {describe(params)}")
    print(f"{'case':<16} {'polarity':<9} {'ours':>10} {'corner err':>11} {'ArUco':>8} {'AprilTag':>9}")
    for case in CASES:
        for polarity in ("normal", "inverted"):
            pol: Polarity = polarity
            ours = wrong = 0
            errors: list[float] = []
            peers_read = dict.fromkeys(PEERS, 0)
            for i in range(poses):
                tag = tags[int(rng.integers(len(tags)))]
                width = rng.uniform(110, 170)
                spec = scenes.posed_spec(tag, rng, width, rng.uniform(0, 45), pol)
                hom = spec.homography
                if case in _CUT_DEPTH:
                    shift = _cut_shift(hom, rng, _CUT_DEPTH[case])
                    while shift is None:  # another roll, until one corner stands out
                        spec = scenes.posed_spec(tag, rng, width, rng.uniform(0, 45), pol)
                        shift = _cut_shift(spec.homography, rng, _CUT_DEPTH[case])
                    hom = shift @ spec.homography
                    spec = scenes.TagSpec(spec.points, spec.triangles, hom, pol, lambda_text=spec.lambda_text,
                                          placement=spec.placement)  # fmt: skip
                poly = _occluder(case, rng)
                grey = int(rng.integers(90, 171))
                blur, noise = float(rng.uniform(0.5, 0.9)), float(rng.uniform(1, 3))
                frame_seed = int(rng.integers(1 << 30))
                frame = scenes.render_scene((480, 640), [spec], np.random.default_rng(frame_seed)).image
                frame = _degrade(_hide(frame, hom, poly, grey), blur, noise, np.random.default_rng(frame_seed))
                if save:
                    path = f"{save}/{case.replace(' ', '_')}_{polarity}_{i}.png"
                    if not cv2.imwrite(path, frame):
                        sys.exit(f"error: could not write {path}")
                dets = det.detect(frame)
                hit = [d for d in dets if d.lambda_text == tag.lambda_text]
                wrong += len(dets) - len(hit)
                if hit:
                    ours += 1
                    truth = scenes.project(hom, _UNIT)
                    side = float(np.sqrt(abs(cv2.contourArea(truth.astype(np.float32)))))
                    errors.append(float(np.abs(hit[0].corners - truth).max()) / side * 100)
                for peer, marker in markers.items():
                    hom_m = hom @ PATCH_TO_DATA_AREA
                    shown = scenes.render_scene(
                        (480, 640), [], np.random.default_rng(frame_seed), extra=[(marker, hom_m)]
                    )
                    img = shown.image if polarity == "normal" else 255 - shown.image
                    img = _degrade(_hide(img, hom, poly, grey), blur, noise, np.random.default_rng(frame_seed))
                    peers_read[peer] += MARKER_ID in reader.ids(peer, img, inverted=polarity == "inverted")
            err = f"{max(errors):.1f} %" if errors else "-"
            aruco, april = peers_read[PEERS[0]], peers_read[PEERS[1]]
            counts = f"{ours:>4}/{poses} {wrong:>2}w {err:>11} {aruco:>5}/{poses} {april:>5}/{poses}"
            print(f"{case:<16} {polarity:<9} {counts}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--poses", type=int, default=40, help="poses per case and polarity (default 40)")
    parser.add_argument("--seed", type=int, default=3, help="draws the poses (default 3)")
    parser.add_argument("--save", metavar="DIR", help="also write our frames as PNGs into DIR")
    add_params_argument(parser)
    args = parser.parse_args()
    detector_params = params_from(args.params, parser)
    if args.poses < 1:
        parser.error("--poses must be at least 1")
    if args.save:
        try:
            Path(args.save).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            parser.error(f"--save: cannot make the folder {args.save} ({exc.strerror})")
    main(args.poses, args.seed, args.save, detector_params)
