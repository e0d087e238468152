"""How many misreads a D = 2 dictionary turns into rejections, compared with the complete dictionary.

Scenes: members of a D = 2 dictionary (the tags a user would print) rendered with the
project's renderer, warped by random camera homographies and degraded *past* the decoder's
design envelope (small tags, strong blur, heavy noise, JPEG) until order types get misread.
Each frame is decoded with the paper's order-type-only decision (``verify=False``) twice:
with the complete lookup (every order type is a valid tag) and with the dictionary lookup.

Printed: per noise level, views, correct reads, misreads accepted by the complete lookup,
misreads accepted by the dictionary, and the share of the complete lookup's misreads that
the dictionary rejects (target ≥ 90 %).

Usage: python benchmarks/dictionary_misreads.py [--views 600] [--seed 1]
Needs a database with every order type: it imports the bundled data with mirrors into a
temporary SQLite file (the reference files hold the same order types).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import cv2
import numpy as np

from ottag_db.core.layout import compute_layout
from ottag_db.decode import Detector, DetectorParams
from ottag_db.files.bundled import bundled_point_files
from ottag_db.printing.geometry import build_tag_geometry
from ottag_db.printing.raster import raster_positions, render_raster
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary
from ottag_db.store.importer import import_point_file
from ottag_db.store.lookups import dictionary_lookup


def build_db(folder: Path, ks: tuple[int, ...]) -> Path:
    """A database in ``folder`` with the bundled data (mirrors: every order type) and a D = 2
    dictionary ``d2`` of the point counts ``ks``; returns its path."""
    path = folder / "misreads.sqlite"
    db = open_database(path)
    try:
        for p, k in bundled_point_files():
            import_point_file(db, p, n=k, with_mirrors=True)
        create_dictionary(db, "d2", DictionaryOptions(ks=ks, min_flip_distance=2))
    finally:
        db.close()
    return path


def view(tag_img: np.ndarray, corners: np.ndarray, rng: np.random.Generator, width: float, tilt: float) -> np.ndarray:
    """Warp a rendered tag into a 640×480 frame: data area about ``width`` px, tilted."""
    h_img, w_img = 480, 640
    side = float(np.linalg.norm(corners[1] - corners[0]))
    s = width / side
    ang = rng.uniform(0, 2 * np.pi)
    c, si = np.cos(ang), np.sin(ang)
    # Perspective by a projective term along a random direction (tilt in degrees, approx.).
    p = np.tan(np.radians(tilt)) / (side * 1.5)
    dirn = rng.normal(size=2)
    dirn /= np.linalg.norm(dirn)
    centre = np.array([tag_img.shape[1] / 2, tag_img.shape[0] / 2])
    t0 = np.array([[1, 0, -centre[0]], [0, 1, -centre[1]], [0, 0, 1]])
    persp = np.array([[1, 0, 0], [0, 1, 0], [p * dirn[0], p * dirn[1], 1]])
    rot = np.array([[s * c, -s * si, 0], [s * si, s * c, 0], [0, 0, 1]])
    shift = np.array([[1, 0, w_img / 2 + rng.uniform(-60, 60)], [0, 1, h_img / 2 + rng.uniform(-40, 40)], [0, 0, 1]])
    hmat = shift @ rot @ persp @ t0
    frame = cv2.warpPerspective(tag_img, hmat, (w_img, h_img), flags=cv2.INTER_AREA, borderValue=255)
    return np.asarray(frame)


def degrade(frame: np.ndarray, rng: np.random.Generator, blur: float, noise: float, quality: int) -> np.ndarray:
    out = cv2.GaussianBlur(frame, (0, 0), blur) if blur > 0 else frame
    out = np.clip(out.astype(np.float64) + rng.normal(scale=noise, size=out.shape), 0, 255).astype(np.uint8)
    ok, enc = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, quality])
    assert ok
    return np.asarray(cv2.imdecode(enc, cv2.IMREAD_GRAYSCALE))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--views", type=int, default=600, help="views per noise level")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--levels",
        nargs="+",
        default=["0.8:4:75:80", "1.0:5:70:70", "1.3:8:60:60", "1.6:10:60:55"],
        help="blur:noise:jpeg:width_px per level",
    )
    ap.add_argument("--k", type=int, nargs="+", default=[6, 7, 8], help="point counts of the dictionary")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        db = open_database(build_db(Path(tmp), tuple(args.k)))
        try:
            full = Detector(dictionary_lookup(db, None), DetectorParams(verify=False))
            d2_lookup = dictionary_lookup(db, "d2")
            d2 = Detector(d2_lookup, DetectorParams(verify=False))
            members = list(d2_lookup)
        finally:
            db.close()
        print(f"D = 2 dictionary: {len(members)} members (k = {', '.join(map(str, args.k))})")
        from collections import Counter

        kinds: Counter[str] = Counter()
        levels = [(float(a), float(b), int(c), float(d)) for a, b, c, d in (x.split(":") for x in args.levels)]
        print(
            f"{'blur':>5} {'noise':>5} {'jpeg':>4} {'px':>4} {'views':>6} {'correct':>8} "
            f"{'misread/complete':>17} {'misread/D2':>11} {'rejected by D2':>15}"
        )
        totals = np.zeros(4, dtype=int)
        for blur, noise, quality, width in levels:
            counts = np.zeros(5, dtype=int)  # views, correct, mis_full, mis_d2, converted
            for _ in range(args.views):
                entry = members[int(rng.integers(len(members)))]
                pts = entry.realizations[0]
                geom = build_tag_geometry(pts, compute_layout(pts).triangles, tag_size=1.0)
                img = render_raster(geom, 120)
                corners = raster_positions(geom, 120).corners
                frame = degrade(view(img, corners, rng, width, rng.uniform(0, 60)), rng, blur, noise, quality)
                got_full = full.detect(frame)
                got_d2 = d2.detect(frame)
                counts[0] += 1
                counts[1] += any(d.lambda_text == entry.lambda_text for d in got_full)
                wrong_full = [d for d in got_full if d.lambda_text != entry.lambda_text]
                wrong_d2 = [d for d in got_d2 if d.lambda_text != entry.lambda_text]
                counts[2] += bool(wrong_full)
                counts[3] += bool(wrong_d2)
                counts[4] += bool(wrong_full) and not wrong_d2
                accepted_d2 = {d.lambda_text for d in wrong_d2}
                for d in wrong_full:
                    where = "other k" if d.k != entry.k else "same k"
                    kinds[where + (", accepted by D2" if d.lambda_text in accepted_d2 else ", rejected by D2")] += 1
            share = counts[4] / counts[2] if counts[2] else float("nan")
            print(
                f"{blur:>5.1f} {noise:>5.0f} {quality:>4d} {width:>4.0f} {counts[0]:>6d} {counts[1]:>8d} "
                f"{counts[2]:>17d} {counts[3]:>11d} {share:>14.1%}"
            )
            totals += counts[[0, 2, 3, 4]]
        print("kinds of misreads (complete lookup):", dict(kinds))
        print(
            f"all levels: {totals[0]} views; misread rate complete {totals[1] / totals[0]:.2%}, "
            f"D = 2 {totals[2] / totals[0]:.2%}; D = 2 turns {totals[3] / max(totals[1], 1):.1%} "
            "of the complete dictionary's misreads into rejections (target >= 90 %)"
        )


if __name__ == "__main__":
    main()
