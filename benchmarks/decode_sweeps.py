"""Decode rate against tilt and distance: Order Type Tags beside ArUco 6×6, printed and plotted.

Usage: python benchmarks/decode_sweeps.py [trials] [out.png]
A 21 cm data area seen by a 640×480 camera with f = 700 px; tilt sweep at 1.5 m, distance sweep
at tilts 0–30°. Each condition renders ``trials`` scenes (random in-plane rotation, tilt axis,
position near the centre, blur σ ≤ 0.8 px, noise σ ≤ 3, JPEG 85) twice: with an Order Type Tag
(the 24 bundled k = 8 tags of largest MP, stored layout and placement, read from the bundled
data imported into a temporary SQLite file as in ``decode_speed.py``) and with an ArUco
DICT_6X6_250 marker of the same size. The plot is drawn with OpenCV (no matplotlib).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
from decode_speed import bundled_tags, drawable  # the benchmark next to this one

from ottag_db.decode import Detector
from ottag_db.printing import scenes

SIZE = 0.21  # m
F = 700.0


def _rates(det, aruco, recs, marker, rng, width_px, tilt_range, trials):  # type: ignore[no-untyped-def]
    k_mat = scenes.camera_matrix(F, 640, 480)
    ok_ours = ok_aruco = 0
    for _ in range(trials):
        rec = recs[int(rng.integers(len(recs)))]
        tilt = rng.uniform(*tilt_range)
        center = (320 + rng.uniform(-30, 30), 240 + rng.uniform(-30, 30))
        r_mat, t = scenes.random_pose(rng, k_mat, SIZE, width_px, tilt, center)
        hom = scenes.pose_homography(k_mat, r_mat, t, SIZE)
        cond = {"blur": rng.uniform(0, 0.8), "noise": rng.uniform(0, 3), "gradient": rng.uniform(0, 0.3), "jpeg": 85}
        seed = int(rng.integers(1 << 30))
        spec = scenes.TagSpec(rec.points, rec.triangles, hom, placement=rec.placement)
        img = scenes.render_scene((480, 640), [spec], np.random.default_rng(seed), **cond).image
        ok_ours += any(d.lambda_text == rec.lambda_text for d in det.detect(img))
        hom_m = hom @ np.array([[1.5, 0, -0.25], [0, 1.5, -0.25], [0, 0, 1.0]])
        img_a = scenes.render_scene((480, 640), [], np.random.default_rng(seed), extra=[(marker, hom_m)], **cond).image
        _, ids, _ = aruco.detectMarkers(img_a)
        ok_aruco += ids is not None and 5 in ids.ravel().tolist()
    return ok_ours / trials, ok_aruco / trials


def _plot(panel: np.ndarray, xs, ours, aru, title: str, xlabel: str) -> None:  # type: ignore[no-untyped-def]
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
    for x in xs:
        p = px(x, 0)
        cv2.putText(panel, f"{x:g}", (p[0] - 10, y1 + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    for ys, color in ((ours, (200, 60, 0)), (aru, (0, 0, 200))):
        pts = np.array([px(x, y) for x, y in zip(xs, ys, strict=True)], np.int32)
        cv2.polylines(panel, [pts], False, color, 2, cv2.LINE_AA)
        for p in pts:
            cv2.circle(panel, tuple(int(v) for v in p), 3, color, -1, cv2.LINE_AA)
    cv2.putText(
        panel, "Order Type Tag", (x1 - 150, y1 - 30), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (200, 60, 0), 1, cv2.LINE_AA
    )
    cv2.putText(panel, "ArUco 6x6", (x1 - 150, y1 - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 200), 1, cv2.LINE_AA)


def main(trials: int = 30, out: str = "decode_sweeps.png") -> None:
    with tempfile.TemporaryDirectory() as tmp:
        lookup, records = bundled_tags(Path(tmp))
    k8 = sorted((r for r in records if r.k == 8), key=lambda r: -r.mp)
    recs = [drawable(r) for r in k8[:24]]
    det = Detector(lookup)
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    aruco = cv2.aruco.ArucoDetector(dictionary, cv2.aruco.DetectorParameters())
    marker = cv2.copyMakeBorder(cv2.aruco.generateImageMarker(dictionary, 5, 400), 100, 100, 100, 100,
                                cv2.BORDER_CONSTANT, value=255)  # fmt: skip
    rng = np.random.default_rng(2018)
    tilts = [0, 10, 20, 30, 40, 50, 60, 70, 75, 80]
    dist = 1.5
    t_ours, t_aru = [], []
    print(f"tilt sweep: 21 cm tag at {dist} m (data area {F * SIZE / dist:.0f} px frontal), {trials} trials each")
    print("tilt°   ours  ArUco")
    for tilt in tilts:
        a, b = _rates(det, aruco, recs, marker, rng, F * SIZE / dist, (tilt, tilt), trials)
        t_ours.append(a)
        t_aru.append(b)
        print(f"{tilt:5d}  {a:5.2f}  {b:5.2f}")
    dists = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0]
    d_ours, d_aru = [], []
    print(f"distance sweep: tilt 0–30°, {trials} trials each")
    print("dist m  px    ours  ArUco")
    for d in dists:
        a, b = _rates(det, aruco, recs, marker, rng, F * SIZE / d, (0, 30), trials)
        d_ours.append(a)
        d_aru.append(b)
        print(f"{d:5.1f}  {F * SIZE / d:4.0f}  {a:5.2f}  {b:5.2f}")
    canvas = np.full((360, 1000, 3), 255, np.uint8)
    _plot(canvas[:, :500], tilts, t_ours, t_aru, f"decode rate vs tilt (21 cm at {dist} m, f=700)", "tilt (deg)")
    _plot(canvas[:, 500:], dists, d_ours, d_aru, "decode rate vs distance (tilt 0-30 deg)", "distance (m)")
    cv2.imwrite(out, canvas)
    print(f"plot: {out}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 30, sys.argv[2] if len(sys.argv) > 2 else "decode_sweeps.png")
