"""Decode rate against tilt and distance: Order Type Tags beside ArUco 6×6 and AprilTag 3, printed and plotted.

Usage: python benchmarks/decode_sweeps.py [--trials N] [--plot sweeps.png] [--seed S] [--paired]
                                          [--compare | --without-model | --other KEY=VALUE ...]
A 21 cm data area seen by a 640×480 camera with f = 700 px: a tilt sweep at 1.5 m (0 … 89°) and a
distance sweep (0.5 … 8 m, tilt 0–30°), each for normal and inverted tags. Each condition renders
``N`` scenes (random in-plane rotation, tilt axis, position near the centre, blur σ ≤ 0.8 px,
noise σ ≤ 3, gradient ≤ 0.3, JPEG 85) three times with the same pose and degradations: with an
Order Type Tag (the 24 bundled k = 8 tags of largest MP with their stored layout and placement, as
``ottag-db export`` draws them, read from the bundled data imported into a temporary SQLite file
as in ``decode_speed.py``), with an ArUco DICT_6X6_250 marker and with an AprilTag 36h11 marker of
the same size (``peers.py``: default detectors; inverted: the marker's tones swapped, ArUco with
``detectInvertedMarker``, AprilTag 3 has no inverted mode). A detection of another ID counts as
wrong (printed; must stay 0). ``--compare`` also runs our decoder without the rectified retry
(``DetectorParams(rectify=False)``) on the same frames: the column ``direct``, its wrong IDs in
parentheses; ``--without-model`` the same without reading by model
(``DetectorParams(model_match=False)``, the column ``no model``: what that setting, 2× faster on
frames of clutter, gives up); ``--other KEY=VALUE ...`` the same with any settings
(``settings.py``; e.g. ``--other last_resort_passes=false``, the column ``other``). For our failures
the most frequent rejection reason of each row is printed. ``--paired`` renders the same
scenes (tag, pose, degradations) in both polarities, so the normal/inverted gap of a row measures
the decoder and not the draw of the poses: with independent draws, one trial of 30 is 3.3 points
and the gap of two independent rates near 0.5 has a standard deviation of 13 points. Without it each
polarity draws its own scenes (the frames of earlier runs). ``--plot PATH`` writes the rates of
both sweeps as a PNG (matplotlib).
"""

from __future__ import annotations

import argparse
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from decode_speed import bundled_tags, drawable  # the benchmark next to this one
from peers import MARKER_ID, PATCH_TO_DATA_AREA, PEERS, PeerReader, marker_patch, plot_lines
from settings import describe, params_from

from ottag_db.core.types import Polarity
from ottag_db.decode import Detector, DetectorParams
from ottag_db.printing import scenes

SIZE = 0.21  # m
F = 700.0
TILTS = (0, 10, 20, 30, 40, 50, 60, 65, 70, 75, 78, 80, 82, 84, 85, 86, 87, 88, 89)
DISTANCES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 7.0, 8.0)
TILT_DISTANCE = 1.5  # m
#: The plot's tilt axis starts here.
PLOT_FROM_TILT = 60


@dataclass
class Row:
    """Counts of one condition (one tilt or distance, one polarity)."""

    trials: int = 0
    ours: int = 0
    other: int = 0  # the second decoder's reads (--compare, --without-model, --other)
    peers: Counter[str] = field(default_factory=Counter)
    wrong: int = 0
    wrong_other: int = 0
    reasons: Counter[str] = field(default_factory=Counter)

    def rate(self, n: int) -> float:
        return n / max(self.trials, 1)


class Sweep:
    """The detectors, tags and marker of one benchmark run."""

    def __init__(self, other: DetectorParams | None) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            lookup, records = bundled_tags(Path(tmp))
        k8 = sorted((r for r in records if r.k == 8), key=lambda r: -r.mp)
        self.recs = [drawable(r) for r in k8[:24]]
        self.det = Detector(lookup)
        self.other = Detector(lookup, other) if other is not None else None
        self.peers = PeerReader()
        self.markers = {peer: marker_patch(peer) for peer in PEERS}
        self.k_mat = scenes.camera_matrix(F, 640, 480)

    def run(
        self, rng: np.random.Generator, width_px: float, tilts: tuple[float, float], pol: Polarity, trials: int
    ) -> Row:
        row = Row()
        for _ in range(trials):
            rec = self.recs[int(rng.integers(len(self.recs)))]
            tilt = rng.uniform(*tilts)
            center = (320 + rng.uniform(-30, 30), 240 + rng.uniform(-30, 30))
            r_mat, t = scenes.random_pose(rng, self.k_mat, SIZE, width_px, tilt, center)
            hom = scenes.pose_homography(self.k_mat, r_mat, t, SIZE)
            # blur σ, noise σ, gradient (drawn in this order: the frames stay those of earlier runs)
            blur, noise, gradient = rng.uniform(0, 0.8), rng.uniform(0, 3), rng.uniform(0, 0.3)
            seed = int(rng.integers(1 << 30))
            spec = scenes.TagSpec(rec.points, rec.triangles, hom, pol, placement=rec.placement)
            img = scenes.render_scene(
                (480, 640), [spec], np.random.default_rng(seed), blur=blur, noise=noise, gradient=gradient, jpeg=85
            ).image
            row.trials += 1
            dets, rejected = self.det.detect_with_rejections(img)
            ok = any(d.lambda_text == rec.lambda_text for d in dets)
            row.ours += ok
            row.wrong += sum(d.lambda_text != rec.lambda_text for d in dets)
            if not ok:
                row.reasons[rejected[0].reason if rejected else "no_candidate"] += 1
            if self.other is not None:
                read = [d.lambda_text for d in self.other.detect(img)]
                row.other += rec.lambda_text in read
                row.wrong_other += sum(x != rec.lambda_text for x in read)
            for peer, patch in self.markers.items():
                marker = patch if pol == "normal" else np.asarray(255 - patch, np.uint8)
                img_m = scenes.render_scene(
                    (480, 640),
                    [],
                    np.random.default_rng(seed),
                    blur=blur,
                    noise=noise,
                    gradient=gradient,
                    jpeg=85,
                    extra=[(marker, hom @ PATCH_TO_DATA_AREA)],
                ).image
                row.peers[peer] += MARKER_ID in self.peers.ids(peer, img_m, inverted=pol == "inverted")
        return row


def _print_row(label: str, rows: dict[Polarity, Row], other: str | None) -> None:
    """One condition's rates, both polarities (``other``: the second decoder's column name)."""
    parts = [label]
    for pol in ("normal", "inverted"):
        r = rows[pol]
        parts.append(f"{r.rate(r.ours):5.2f}")
        if other:
            parts.append(f"{r.rate(r.other):{len(other)}.2f}")
        parts += [f"{r.rate(r.peers[peer]):5.2f}" for peer in PEERS]
    wrong = sum(r.wrong for r in rows.values())
    reasons = rows["normal"].reasons + rows["inverted"].reasons
    parts.append(f"{wrong:5d}" + (f" ({sum(r.wrong_other for r in rows.values())})" if other else ""))
    parts.append(" ".join(f"{k}:{v}" for k, v in reasons.most_common(3)))
    print("  ".join(parts), flush=True)


def _header(first: str, other: str | None) -> None:
    """The table's two header lines (``other``: the second decoder's column)."""
    cols = ["ours", other, "ArUco", "April"] if other else ["ours", "ArUco", "April"]
    norm = "  ".join(f"{c:>5}" for c in cols)  # (the second decoder's column as wide as its name)
    print(f"{first}  {'normal':^{len(norm)}}  {'inverted':^{len(norm)}}  wrong  our failures")
    print(f"{' ' * len(first)}  {norm}  {norm}")


def _series(rows: list[dict[Polarity, Row]]) -> dict[str, list[float]]:
    """Rates per detector and polarity, in the order of the rows."""
    out: dict[str, list[float]] = {}
    for pol in ("normal", "inverted"):
        out[f"Order Type Tag, {pol}"] = [r[pol].rate(r[pol].ours) for r in rows]
        for peer in PEERS:
            if pol == "normal" or peer == "ArUco 6x6":  # AprilTag 3 has no inverted mode
                out[f"{peer}, {pol}"] = [r[pol].rate(r[pol].peers[peer]) for r in rows]
    return out


#: The second decoders of ``--compare`` and ``--without-model``: column name and settings.
OTHERS = {
    "compare": ("direct", DetectorParams(rectify=False)),
    "without_model": ("no model", DetectorParams(model_match=False)),
}


def main(
    trials: int, plot: str | None, other: tuple[str, DetectorParams] | None, seed: int, paired: bool = False
) -> None:
    column, params = other if other else (None, None)
    if params is not None:
        print(f"{column}: ours with {describe(params)}")
    sweep = Sweep(params)
    rng = np.random.default_rng(seed)
    pols: tuple[Polarity, Polarity] = ("normal", "inverted")

    def both(width_px: float, tilts: tuple[float, float]) -> dict[Polarity, Row]:
        if not paired:
            return {pol: sweep.run(rng, width_px, tilts, pol, trials) for pol in pols}
        scenes_seed = int(rng.integers(1 << 30))  # one draw of scenes, rendered in each polarity
        return {pol: sweep.run(np.random.default_rng(scenes_seed), width_px, tilts, pol, trials) for pol in pols}

    if paired:
        print("paired: the same scenes in both polarities")
    width = F * SIZE / TILT_DISTANCE
    print(f"tilt sweep: 21 cm tag at {TILT_DISTANCE} m (data area {width:.0f} px frontal), {trials} trials each")
    _header("tilt°", column)
    tilt_rows = []
    for tilt in TILTS:
        rows = both(width, (tilt, tilt))
        tilt_rows.append(rows)
        _print_row(f"{tilt:5d}", rows, column)
    print(f"distance sweep: tilt 0–30°, {trials} trials each")
    _header("dist m    px", column)
    dist_rows = []
    for d in DISTANCES:
        rows = both(F * SIZE / d, (0, 30))
        dist_rows.append(rows)
        _print_row(f"{d:6.1f}  {F * SIZE / d:4.0f}", rows, column)
    wrong = sum(r.wrong for rows in tilt_rows + dist_rows for r in rows.values())
    second = sum(r.wrong_other for rows in tilt_rows + dist_rows for r in rows.values())
    print(f"wrong IDs in all conditions: {wrong}" + (f" ({column}: {second})" if column else ""))
    if plot:
        # the tilt panel from PLOT_FROM_TILT on, where the rates part (the printout has every row)
        steep = [i for i, tilt in enumerate(TILTS) if tilt >= PLOT_FROM_TILT]
        plot_lines(
            plot,
            [
                (f"decode rate vs tilt (21 cm at {TILT_DISTANCE} m, f = 700 px)", "tilt (°)", "rate",
                 [TILTS[i] for i in steep], _series([tilt_rows[i] for i in steep])),
                ("decode rate vs distance (tilt 0–30°)", "distance (m)", "rate", DISTANCES, _series(dist_rows)),
            ],
        )  # fmt: skip


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=30, help="scenes per condition and polarity")
    ap.add_argument("--plot", default=None, metavar="PATH", help="write the rates as a PNG (matplotlib)")
    others = ap.add_mutually_exclusive_group()
    others.add_argument("--compare", action="store_true", help="also run the decoder without the rectified retry")
    others.add_argument("--without-model", action="store_true", help="also run the decoder without reading by model")
    others.add_argument("--other", nargs="+", metavar="KEY=VALUE", help="also run the decoder with these settings")
    ap.add_argument("--seed", type=int, default=2018)
    ap.add_argument("--paired", action="store_true", help="the same scenes in both polarities")
    args = ap.parse_args()
    chosen = "compare" if args.compare else "without_model" if args.without_model else None
    other = ("other", params_from(args.other, ap, "--other")) if args.other else OTHERS[chosen] if chosen else None
    main(args.trials, args.plot, other, args.seed, args.paired)
