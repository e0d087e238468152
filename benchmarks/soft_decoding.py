"""Soft decoding: how many ``low_margin`` rejections become correct detections, and wrong IDs.

Usage: python benchmarks/soft_decoding.py [--frames N] [--seed S] [--width LO HI] [--tilt LO HI]

Synthetic 640×480 frames (f = 700 px) of one tag each, small and tilted so that many readings
fall under the decoder's 1 px margin: frontal-equivalent data-area side uniform in ``--width``
px (default 50 … 110), tilt uniform in ``--tilt`` degrees (default 40 … 80), random in-plane
rotation and position near the centre, blur σ ≤ 0.9 px, noise σ ≤ 4, gradient ≤ 0.3, JPEG 85;
normal and inverted tags. Each frame is decoded twice with the same lookup: soft decoding off
(``DetectorParams(soft_max_flips=0)``: a reading under the margin is rejected) and on (the
defaults). Two lookups, each with its own tags:

- **complete**: every order type of k = 5 … 8 with mirrors (any misread is a valid ID); the
  tags are every bundled order type of those k as ``ottag-db export`` draws them;
- **D = 3**: a flip-distance-3 dictionary of 8-point tags, both polarities
  (``create_dictionary(..., DictionaryOptions(ks=(8,), min_flip_distance=3, polarity="both"))``);
  the tags are its members as printed.

Printed per lookup: frames; correct detections off and on; the frames rejected ``low_margin``
with soft decoding off, and how many of them soft decoding turns into correct detections and
into wrong IDs; wrong IDs off and on over all frames (a detection of another ID than the tag's);
the soft-decoded detections by number of flipped triples; the decoding time per frame off and
on (the same frames, one after the other: compare, on a shared machine). The bundled data is imported (with
mirrors) into a temporary SQLite file, as ``decode_speed.py`` does.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ottag_db.core.lookup import MemoryLookup
from ottag_db.decode import Detector, DetectorParams
from ottag_db.files.bundled import bundled_point_files
from ottag_db.printing import scenes
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary, dictionary_tag_records
from ottag_db.store.importer import import_point_file
from ottag_db.store.lookups import dictionary_lookup, load_lookup
from ottag_db.store.tags import TagRecord, select_tags

SIZE = 0.21  # m, printed data area (only its ratio to the distance matters)
KS = (5, 6, 7, 8)


@dataclass
class Counts:
    """Tallies of one lookup."""

    frames: int = 0
    correct_off: int = 0
    correct_on: int = 0
    low_margin_off: int = 0
    low_margin_fixed: int = 0
    low_margin_wrong: int = 0
    wrong_off: int = 0
    wrong_on: int = 0
    soft: Counter[tuple[int, bool]] = field(default_factory=Counter)
    wrong: list[str] = field(default_factory=list)
    seconds_off: float = 0.0
    seconds_on: float = 0.0


def _drawable(rec: TagRecord) -> scenes.DrawableTag:
    return scenes.drawable_from_file_order(
        rec.lambda_text, rec.points, rec.labeling, rec.triangles, rec.placement, rec.printed_mp_unit
    )


def build(folder: Path) -> dict[str, tuple[MemoryLookup, list[tuple[scenes.DrawableTag, tuple[str, ...]]]]]:
    """The two lookups with their tags (and the polarities each tag is printed in)."""
    db = open_database(folder / "soft.sqlite")
    try:
        for path, k in bundled_point_files():
            import_point_file(db, path, n=k, with_mirrors=True)
        create_dictionary(db, "d3", DictionaryOptions(ks=(8,), min_flip_distance=3, polarity="both"))
        complete = load_lookup(db, ks=KS)
        tags: list[tuple[scenes.DrawableTag, tuple[str, ...]]] = [
            (_drawable(r), ("normal", "inverted")) for r in select_tags(db, ks=KS)
        ]
        d3 = dictionary_lookup(db, "d3")
        info, records = dictionary_tag_records(db, "d3")
    finally:
        db.close()
    members: dict[str, tuple[scenes.DrawableTag, list[str]]] = {}
    for m, r in zip(info.members, records, strict=True):
        members.setdefault(r.lambda_text, (_drawable(r), []))[1].append(m.polarity)
    return {
        "complete k=5..8": (complete, tags),
        "D=3 k=8": (d3, [(t, tuple(p)) for t, p in members.values()]),
    }


def run(
    lookup: MemoryLookup,
    tags: list[tuple[scenes.DrawableTag, tuple[str, ...]]],
    frames: int,
    rng: np.random.Generator,
    width: tuple[float, float],
    tilt: tuple[float, float],
) -> Counts:
    """Decode ``frames`` random frames with soft decoding off and on."""
    off = Detector(lookup, DetectorParams(soft_max_flips=0))
    on = Detector(lookup)
    k_mat = scenes.camera_matrix(700.0, 640, 480)
    c = Counts()
    for _ in range(frames):
        tag, pols = tags[int(rng.integers(len(tags)))]
        pol = pols[int(rng.integers(len(pols)))]
        center = (320 + rng.uniform(-40, 40), 240 + rng.uniform(-40, 40))
        r_mat, t = scenes.random_pose(rng, k_mat, SIZE, rng.uniform(*width), rng.uniform(*tilt), center)
        hom = scenes.pose_homography(k_mat, r_mat, t, SIZE)
        spec = scenes.TagSpec(tag.points, tag.triangles, hom, pol, placement=tag.placement)  # type: ignore[arg-type]
        img = scenes.render_scene(
            (480, 640), [spec], rng,
            blur=rng.uniform(0, 0.9), noise=rng.uniform(0, 4), gradient=rng.uniform(0, 0.3), jpeg=85,
        ).image  # fmt: skip
        c.frames += 1
        t0 = time.perf_counter()
        d_off, rej_off = off.detect_with_rejections(img)
        t1 = time.perf_counter()
        d_on = on.detect(img)
        c.seconds_on += time.perf_counter() - t1
        c.seconds_off += t1 - t0
        ok_off = any(d.lambda_text == tag.lambda_text for d in d_off)
        ok_on = any(d.lambda_text == tag.lambda_text for d in d_on)
        wrong_on = sum(d.lambda_text != tag.lambda_text for d in d_on)
        c.correct_off += ok_off
        c.correct_on += ok_on
        c.wrong_off += sum(d.lambda_text != tag.lambda_text for d in d_off)
        c.wrong_on += wrong_on
        for mode, dets in (("off", d_off), ("on", d_on)):
            c.wrong += [
                f"{mode}: k = {tag.k} tag read as k = {d.k}, margin {d.margin_px:.2f} px, "
                f"corrected_flips {d.corrected_flips}"
                for d in dets
                if d.lambda_text != tag.lambda_text
            ]
        for d in d_on:
            if d.corrected_flips is not None:
                c.soft[(d.corrected_flips, d.lambda_text == tag.lambda_text)] += 1
        if not ok_off and any(r.reason == "low_margin" for r in rej_off):
            c.low_margin_off += 1
            c.low_margin_fixed += ok_on
            c.low_margin_wrong += wrong_on > 0
    return c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=300, help="frames per lookup")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--width", type=float, nargs=2, default=(50.0, 110.0), help="data-area side range, px")
    ap.add_argument("--tilt", type=float, nargs=2, default=(40.0, 80.0), help="tilt range, degrees")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        setups = build(Path(tmp))
    print(f"{args.frames} frames per lookup, width {args.width[0]:g}…{args.width[1]:g} px, "
          f"tilt {args.tilt[0]:g}…{args.tilt[1]:g}°, seed {args.seed}")  # fmt: skip
    print(f"{'lookup':<16} {'frames':>6} {'correct off':>11} {'on':>5} {'low_margin off':>14} "
          f"{'→ correct':>9} {'→ wrong':>7} {'wrong off':>9} {'wrong on':>8}  soft (flips: correct/wrong)")  # fmt: skip
    for i, (name, (lookup, tags)) in enumerate(setups.items()):
        c = run(lookup, tags, args.frames, np.random.default_rng([args.seed, i]), tuple(args.width), tuple(args.tilt))
        soft = " ".join(f"{n}:{c.soft[(n, True)]}/{c.soft[(n, False)]}" for n in range(3))
        row = f"{name:<16} {c.frames:>6} {c.correct_off:>11} {c.correct_on:>5} {c.low_margin_off:>14} "
        row += f"{c.low_margin_fixed:>9} {c.low_margin_wrong:>7} {c.wrong_off:>9} {c.wrong_on:>8}  {soft}"
        row += f"  ms/frame off {1000 * c.seconds_off / c.frames:.1f}, on {1000 * c.seconds_on / c.frames:.1f}"
        print(row, flush=True)
        for w in c.wrong:
            print(f"  wrong ID, {w}", flush=True)


if __name__ == "__main__":
    main()
