"""Decode rate against tilt and distance: Order Type Tags beside ArUco 6×6, printed and plotted.

Usage: python benchmarks/decode_sweeps.py [--trials N] [--out sweeps.png] [--compare] [--seed S] [--paired]
A 21 cm data area seen by a 640×480 camera with f = 700 px: a tilt sweep at 1.5 m (0 … 89°) and a
distance sweep (0.5 … 8 m, tilt 0–30°), each for normal and inverted tags. Each condition renders
``N`` scenes (random in-plane rotation, tilt axis, position near the centre, blur σ ≤ 0.8 px,
noise σ ≤ 3, gradient ≤ 0.3, JPEG 85) twice with the same pose and degradations: with an Order
Type Tag (the 24 bundled k = 8 tags of largest MP with their stored layout and placement, as
``ottag-db export`` draws them, read from the bundled data imported into a temporary SQLite file
as in ``decode_speed.py``) and with an ArUco DICT_6X6_250 marker of the same size (inverted: the
marker's tones swapped, read with ``detectInvertedMarker``). A detection of another ID counts as
wrong (printed; must stay 0). ``--compare`` also runs our decoder without the rectified retry
(``DetectorParams(rectify=False)``) on the same frames: the column ``direct``, its wrong IDs in
parentheses. For our failures
the most frequent rejection reason of each row is printed. ``--paired`` renders the same
scenes (tag, pose, degradations) in both polarities, so the normal/inverted gap of a row measures
the decoder and not the draw of the poses: with independent draws, one trial of 30 is 3.3 points
and the gap of two independent rates near 0.5 has a standard deviation of 13 points. Without it each
polarity draws its own scenes (the frames of earlier runs). The plot is drawn with OpenCV
(matplotlib is not a dependency).
"""

from __future__ import annotations

import argparse
import tempfile
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from decode_speed import bundled_tags, drawable  # the benchmark next to this one
from numpy.typing import NDArray

from ottag_db.core.types import Polarity
from ottag_db.decode import Detector, DetectorParams
from ottag_db.printing import scenes

SIZE = 0.21  # m
F = 700.0
TILTS = (0, 10, 20, 30, 40, 50, 60, 65, 70, 75, 78, 80, 82, 84, 85, 86, 87, 88, 89)
DISTANCES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 7.0, 8.0)
TILT_DISTANCE = 1.5  # m


@dataclass
class Row:
    """Counts of one condition (one tilt or distance, one polarity)."""

    trials: int = 0
    ours: int = 0
    direct: int = 0
    aruco: int = 0
    wrong: int = 0
    wrong_direct: int = 0
    reasons: Counter[str] = field(default_factory=Counter)

    def rate(self, n: int) -> float:
        return n / max(self.trials, 1)


class Sweep:
    """The detectors, tags and marker of one benchmark run."""

    def __init__(self, compare: bool) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            lookup, records = bundled_tags(Path(tmp))
        k8 = sorted((r for r in records if r.k == 8), key=lambda r: -r.mp)
        self.recs = [drawable(r) for r in k8[:24]]
        self.det = Detector(lookup)
        self.direct = Detector(lookup, DetectorParams(rectify=False)) if compare else None
        dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
        self.aruco = cv2.aruco.ArucoDetector(dictionary, cv2.aruco.DetectorParameters())
        inv = cv2.aruco.DetectorParameters()
        inv.detectInvertedMarker = True
        self.aruco_inv = cv2.aruco.ArucoDetector(dictionary, inv)
        self.marker: NDArray[np.uint8] = np.asarray(
            cv2.copyMakeBorder(
                cv2.aruco.generateImageMarker(dictionary, 5, 400), 100, 100, 100, 100, cv2.BORDER_CONSTANT, value=255
            ),
            np.uint8,
        )
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
            if self.direct is not None:
                read = [d.lambda_text for d in self.direct.detect(img)]
                row.direct += rec.lambda_text in read
                row.wrong_direct += sum(x != rec.lambda_text for x in read)
            hom_m = hom @ np.array([[1.5, 0, -0.25], [0, 1.5, -0.25], [0, 0, 1.0]])
            marker = self.marker if pol == "normal" else np.asarray(255 - self.marker, np.uint8)
            img_a = scenes.render_scene(
                (480, 640),
                [],
                np.random.default_rng(seed),
                blur=blur,
                noise=noise,
                gradient=gradient,
                jpeg=85,
                extra=[(marker, hom_m)],
            ).image
            _, ids, _ = (self.aruco if pol == "normal" else self.aruco_inv).detectMarkers(img_a)
            row.aruco += ids is not None and 5 in ids.ravel().tolist()
        return row


def _print_row(label: str, rows: dict[Polarity, Row], compare: bool) -> None:
    parts = [label]
    for pol in ("normal", "inverted"):
        r = rows[pol]
        parts.append(f"{r.rate(r.ours):5.2f}")
        if compare:
            parts.append(f"{r.rate(r.direct):6.2f}")
        parts.append(f"{r.rate(r.aruco):5.2f}")
    wrong = sum(r.wrong for r in rows.values())
    reasons = rows["normal"].reasons + rows["inverted"].reasons
    parts.append(f"{wrong:5d}" + (f" ({sum(r.wrong_direct for r in rows.values())})" if compare else ""))
    parts.append(" ".join(f"{k}:{v}" for k, v in reasons.most_common(3)))
    print("  ".join(parts), flush=True)


def _header(first: str, compare: bool) -> None:
    cols = ["ours", "direct", "ArUco"] if compare else ["ours", "ArUco"]
    norm = "  ".join(f"{c:>5}" for c in cols)
    print(f"{first}  {'normal':^{len(norm)}}  {'inverted':^{len(norm)}}  wrong  our failures")
    print(f"{' ' * len(first)}  {norm}  {norm}")


def _plot(
    panel: np.ndarray,
    xs: Sequence[float],
    series: list[tuple[list[float], tuple[int, int, int], str, bool]],
    title: str,
    xlabel: str,
) -> None:
    h, w = panel.shape[:2]
    x0, y0, x1, y1 = 60, 40, w - 20, h - 50
    cv2.rectangle(panel, (x0, y0), (x1, y1), (0, 0, 0), 1)
    cv2.putText(panel, title, (x0, 25), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(panel, xlabel, ((x0 + x1) // 2 - 40, h - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    lo, hi = min(xs), max(xs)

    def px(x: float, y: float) -> tuple[int, int]:
        return int(x0 + (x - lo) / (hi - lo) * (x1 - x0)), int(y1 - y * (y1 - y0))

    for v in (0.0, 0.25, 0.5, 0.75, 1.0):
        p = px(lo, v)
        cv2.line(panel, (x0, p[1]), (x1, p[1]), (220, 220, 220), 1)
        cv2.putText(panel, f"{v:.2f}", (8, p[1] + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    last = -np.inf
    for x in xs:  # tick labels no closer than 1/12 of the axis
        if x - last < (hi - lo) / 12 and x != xs[-1]:
            continue
        last = x
        p = px(x, 0)
        cv2.putText(panel, f"{x:g}", (p[0] - 10, y1 + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    for i, (ys, color, name, inverted) in enumerate(series):
        # normal: thick line, filled dots; inverted: thin line, open circles
        pts = np.array([px(x, y) for x, y in zip(xs, ys, strict=True)], np.int32)
        cv2.polylines(panel, [pts], False, color, 1 if inverted else 2, cv2.LINE_AA)
        for p in pts:
            cv2.circle(panel, (int(p[0]), int(p[1])), 4 if inverted else 3, color, 1 if inverted else -1, cv2.LINE_AA)
        cv2.putText(panel, name, (x0 + 10, y1 - 12 - 18 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.45, color, 1, cv2.LINE_AA)


def _series(rows: list[dict[Polarity, Row]]) -> list[tuple[list[float], tuple[int, int, int], str, bool]]:
    out = []
    styles: tuple[tuple[Polarity, bool], ...] = (("normal", False), ("inverted", True))
    for pol, inverted in styles:
        out.append(([r[pol].rate(r[pol].ours) for r in rows], (200, 60, 0), f"Order Type Tag, {pol}", inverted))
        out.append(([r[pol].rate(r[pol].aruco) for r in rows], (0, 0, 200), f"ArUco 6x6, {pol}", inverted))
    return out


def main(trials: int, out: str, compare: bool, seed: int, paired: bool = False) -> None:
    sweep = Sweep(compare)
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
    _header("tilt°", compare)
    tilt_rows = []
    for tilt in TILTS:
        rows = both(width, (tilt, tilt))
        tilt_rows.append(rows)
        _print_row(f"{tilt:5d}", rows, compare)
    print(f"distance sweep: tilt 0–30°, {trials} trials each")
    _header("dist m    px", compare)
    dist_rows = []
    for d in DISTANCES:
        rows = both(F * SIZE / d, (0, 30))
        dist_rows.append(rows)
        _print_row(f"{d:6.1f}  {F * SIZE / d:4.0f}", rows, compare)
    wrong = sum(r.wrong for rows in tilt_rows + dist_rows for r in rows.values())
    direct = sum(r.wrong_direct for rows in tilt_rows + dist_rows for r in rows.values())
    print(f"wrong IDs in all conditions: {wrong}" + (f" (direct: {direct})" if compare else ""))
    canvas = np.full((420, 1200, 3), 255, np.uint8)
    _plot(
        canvas[:, :600],
        TILTS,
        _series(tilt_rows),
        f"decode rate vs tilt (21 cm at {TILT_DISTANCE} m, f=700)",
        "tilt (deg)",
    )
    _plot(canvas[:, 600:], DISTANCES, _series(dist_rows), "decode rate vs distance (tilt 0-30 deg)", "distance (m)")
    cv2.imwrite(out, canvas)
    print(f"plot: {out}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=30, help="scenes per condition and polarity")
    ap.add_argument("--out", default="decode_sweeps.png", help="plot file (PNG)")
    ap.add_argument("--compare", action="store_true", help="also run the decoder without the rectified retry")
    ap.add_argument("--seed", type=int, default=2018)
    ap.add_argument("--paired", action="store_true", help="the same scenes in both polarities")
    args = ap.parse_args()
    main(args.trials, args.out, args.compare, args.seed, args.paired)
