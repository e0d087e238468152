"""Tags at the edge of the picture: one corner from 2 % inside to 30 % outside the frame, ours and
other programs' drawings — reads and wrong IDs per cut, beside ArUco and AprilTag 3.

Usage: python benchmarks/decode_frame_edge.py [--frames N] [--seed S] [-q]

Each frame (640×480, f = 700 px) holds one 8-point tag, data area 90–300 px wide, tilt 0–50°,
shifted so that one data-area corner lies a drawn depth outside the frame (of the side;
negative: inside), in four bands: −2…2 %, 2…6 %, 6…10 % and 10…30 %. Half the frames draw the
tag as the project prints it, half as another program might (``decode_foreign.foreign_patch``:
other triangles, a margin of 5–12 %), normal and inverted in turn; camera blur, noise and
JPEG 85. The lookup holds every order type of 3–8 points, so a point hidden beyond the edge could
read as another order type: any other ID is wrong. ArUco 6×6 and AprilTag 36h11 markers of the
same size are drawn at the same poses (AprilTag 3 reads no inverted markers).

A data area the frame cuts must show its stored print (a point may be hidden) unless only a
sliver of its border is cut (``decode.outlines.cut_by_frame_only``): another program's drawing
then reads from its points. Needs ``pip install '.[bench]'`` (pupil-apriltags).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from ottag_db.core.types import Polarity
from ottag_db.decode import Detector
from ottag_db.printing import scenes

sys.path.insert(0, str(Path(__file__).resolve().parent))
from decode_foreign import _patch_to_data_area, foreign_patch  # the benchmarks next door
from decode_occlusion import _cut_shift, _degrade
from decode_speed import bundled_tags, drawable
from peers import MARKER_ID, PATCH_TO_DATA_AREA, PEERS, PeerReader, marker_patch

#: The bands of how far one corner lies outside the frame, of the data area's side.
BANDS = ((-0.02, 0.02), (0.02, 0.06), (0.06, 0.10), (0.10, 0.30))


def main(frames: int, seed: int, quiet: bool) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        lookup, records = bundled_tags(Path(tmp))
    det = Detector(lookup)
    reader = PeerReader()
    markers = {peer: marker_patch(peer) for peer in PEERS}
    tags = [drawable(t) for t in records if t.k == 8 and scenes.min_width_px(t.printed_mp_unit) <= 100]
    rng = np.random.default_rng(seed)
    # (drawing, band) -> [frames, read, wrong, ArUco, AprilTag]
    counts: dict[tuple[str, int], list[int]] = {}
    for i in range(frames):
        if not quiet:
            print(f"\rframe {i + 1}/{frames}", end="", file=sys.stderr, flush=True)
        tag = tags[int(rng.integers(len(tags)))]
        drawing = "other program" if i % 2 else "ours"
        polarity: Polarity = "inverted" if (i // 2) % 2 else "normal"
        band = int(rng.integers(len(BANDS)))
        width, tilt = rng.uniform(90, 300), rng.uniform(0, 50)
        spec = scenes.posed_spec(tag, rng, width, tilt, polarity)
        shift = _cut_shift(spec.homography, rng, BANDS[band])
        while shift is None:  # another roll, until one corner stands out
            spec = scenes.posed_spec(tag, rng, width, rng.uniform(0, 50), polarity)
            shift = _cut_shift(spec.homography, rng, BANDS[band])
        hom = shift @ spec.homography
        blur, noise = float(rng.uniform(0.3, 0.9)), float(rng.uniform(1, 3))
        frame_seed = int(rng.integers(1 << 30))
        if drawing == "ours":
            moved = scenes.TagSpec(spec.points, spec.triangles, hom, polarity, lambda_text=spec.lambda_text,
                                   placement=spec.placement)  # fmt: skip
            image = scenes.render_scene((480, 640), [moved], np.random.default_rng(frame_seed)).image
        else:
            patch = foreign_patch(tag, rng)
            drawn = patch if polarity == "normal" else 255 - patch
            extra = [(drawn.astype(np.uint8), hom @ _patch_to_data_area())]
            image = scenes.render_scene((480, 640), [], np.random.default_rng(frame_seed), extra=extra).image
        image = _degrade(image, blur, noise, np.random.default_rng(frame_seed))
        ids = [d.lambda_text for d in det.detect(image)]
        row = counts.setdefault((drawing, band), [0] * 5)
        row[0] += 1
        row[1] += tag.lambda_text in ids
        row[2] += sum(x != tag.lambda_text for x in ids)
        for j, (peer, marker) in enumerate(markers.items()):
            shown = scenes.render_scene(
                (480, 640), [], np.random.default_rng(frame_seed), extra=[(marker, hom @ PATCH_TO_DATA_AREA)]
            ).image
            shown = shown if polarity == "normal" else 255 - shown
            shown = _degrade(shown, blur, noise, np.random.default_rng(frame_seed))
            row[3 + j] += MARKER_ID in reader.ids(peer, shown, inverted=polarity == "inverted")
    if not quiet:
        print(file=sys.stderr)
    print(f"{frames} frames (seed {seed}), both polarities; read / frames, wrong IDs; peers at the same poses")
    print(f"{'drawing':<14} {'corner outside':>15} {'ours':>9} {'wrong':>6} {'ArUco':>9} {'AprilTag':>9}")
    for (drawing, band), (n, read, wrong, aruco, april) in sorted(counts.items()):
        lo, hi = BANDS[band]
        cut = f"{lo * 100:+.0f}…{hi * 100:+.0f} %"
        print(f"{drawing:<14} {cut:>15} {read:>4}/{n:<4} {wrong:>6} {aruco:>4}/{n:<4} {april:>4}/{n:<4}")
    total_wrong = sum(row[2] for row in counts.values())
    print(f"wrong IDs in all: {total_wrong}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=400, help="frames in all (default 400)")
    parser.add_argument("--seed", type=int, default=1, help="draws the frames (default 1)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    args = parser.parse_args()
    if args.frames < 1:
        parser.error("--frames must be at least 1")
    main(args.frames, args.seed, args.quiet)
