"""Normal against inverted tags on the same poses: the gap the tilt sweep measures, paired.

Usage: python benchmarks/decode_polarity.py [--poses N] [--tilts 84 85 86] [--background G] [--seed S]

The tilt sweep of ``decode_sweeps.py`` draws its normal and inverted scenes independently, so
at 30 trials a condition its two rates differ by several points by chance alone. Here each pose
is rendered twice with the same tag, pose, blur, noise, light and JPEG: once normal, once
inverted. Same geometry as the sweep: a 21 cm data area at 1.5 m, f = 700 px, 640×480, the 24
bundled k = 8 tags of largest MP as ``ottag-db export`` draws them, tilt fixed per row, random
in-plane rotation, tilt axis and position near the centre; blur σ ≤ 0.8 px, noise σ ≤ 3,
gradient ≤ 0.3, JPEG 85. ``--background`` sets the grey level of the frame around the tag's
quiet zone (the sweep's is 200; at 55 a normal tag is close to the photometric negative of an
inverted tag on the usual background, which separates what the decoder does from what the
scene does).

Printed per tilt: poses; reads of the normal and of the inverted tag; the pairs read in one
polarity only (normal only / inverted only: the paired difference); wrong IDs (a detection of
another ID; must stay 0); the most frequent rejection reason of each polarity's failures.
"""

from __future__ import annotations

import argparse
from collections import Counter
from collections.abc import Sequence

import numpy as np
from decode_sweeps import SIZE, TILT_DISTANCE, Sweep  # the benchmark next to this one

from ottag_db.core.types import Polarity
from ottag_db.printing import scenes

POLARITIES: tuple[Polarity, Polarity] = ("normal", "inverted")


def main(poses: int, tilts: Sequence[float], background: int, seed: int) -> None:
    sweep = Sweep(other=None)
    width = sweep.k_mat[0, 0] * SIZE / TILT_DISTANCE
    print(
        f"{poses} poses per tilt, each rendered normal and inverted; 21 cm data area at {TILT_DISTANCE} m "
        f"({width:.0f} px frontal), background grey {background}, seed {seed}"
    )
    print(f"{'tilt°':>6} {'poses':>5} {'normal':>6} {'inverted':>8} {'normal only':>11} {'inverted only':>13} "
          f"{'wrong':>5}  failures (most frequent reason): normal; inverted")  # fmt: skip
    total_wrong = 0
    for tilt in tilts:
        rng = np.random.default_rng([seed, round(10 * tilt)])
        read = dict.fromkeys(POLARITIES, 0)
        only = dict.fromkeys(POLARITIES, 0)
        reasons: dict[Polarity, Counter[str]] = {pol: Counter() for pol in POLARITIES}
        wrong = 0
        for _ in range(poses):
            rec = sweep.recs[int(rng.integers(len(sweep.recs)))]
            center = (320 + rng.uniform(-30, 30), 240 + rng.uniform(-30, 30))
            r_mat, t = scenes.random_pose(rng, sweep.k_mat, SIZE, width, tilt, center)
            hom = scenes.pose_homography(sweep.k_mat, r_mat, t, SIZE)
            blur, noise, gradient = rng.uniform(0, 0.8), rng.uniform(0, 3), rng.uniform(0, 0.3)
            frame_seed = int(rng.integers(1 << 30))
            ok: dict[Polarity, bool] = {}
            for pol in POLARITIES:
                spec = scenes.TagSpec(rec.points, rec.triangles, hom, pol, placement=rec.placement)
                img = scenes.render_scene(
                    (480, 640), [spec], np.random.default_rng(frame_seed),
                    background=background, blur=blur, noise=noise, gradient=gradient, jpeg=85,
                ).image  # fmt: skip
                dets, rejected = sweep.det.detect_with_rejections(img)
                ok[pol] = any(d.lambda_text == rec.lambda_text for d in dets)
                wrong += sum(d.lambda_text != rec.lambda_text for d in dets)
                read[pol] += ok[pol]
                if not ok[pol]:
                    reasons[pol][rejected[0].reason if rejected else "no_candidate"] += 1
            for pol, other in (POLARITIES, POLARITIES[::-1]):
                only[pol] += ok[pol] and not ok[other]
        total_wrong += wrong
        why = "; ".join((f"{r.most_common(1)[0][0]} {r.most_common(1)[0][1]}" if r else "-") for r in reasons.values())
        print(
            f"{tilt:6g} {poses:5d} {read['normal']:6d} {read['inverted']:8d} {only['normal']:11d} "
            f"{only['inverted']:13d} {wrong:5d}  {why}",
            flush=True,
        )
    print(f"wrong IDs: {total_wrong}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, default=60, help="poses per tilt (each rendered in both polarities)")
    ap.add_argument("--tilts", type=float, nargs="+", default=[84.0, 85.0, 86.0], help="tilts, degrees")
    ap.add_argument("--background", type=int, default=200, help="grey level of the frame around the tag")
    ap.add_argument("--seed", type=int, default=2018)
    args = ap.parse_args()
    if args.poses < 1 or not 0 <= args.background <= 255:
        ap.error("--poses must be at least 1 and --background within 0…255")
    if not all(0 <= t < 90 for t in args.tilts):
        ap.error("--tilts must lie in 0…90° (90 and beyond: the tag is seen edge-on or from behind)")
    main(args.poses, args.tilts, args.background, args.seed)
