"""Realization at scale (issue 14, item 3): the batched realizer against the per-set SLSQP one.

Usage: python benchmarks/realize_speed.py [--k9 FILE] [--sample 1000] [--old-sample N] [--k8-old 100] [--seed 0]

Both realizers run in this process, one after the other, on the same sets with the same seed;
the figures are CPU seconds of this process (``time.process_time``), so they compare the two
even on a loaded machine (where the wall time would not).

- **k = 8.** The bundled ``data/ottag-k08.b08`` (3,315 sets) was made by the per-set
  realizer (``default_effort(8)``: SLSQP from 3 starts, rounding, exact roundings of the hard
  sets, integer search, tilt choice) from the realizations of the enumeration, seed 0. The
  batched realizer (``default_effort(9)``: the compiled soft-min ascent of whole batches,
  4,000 steps, no SLSQP; incremental integer search) realizes the same order types from the same enumeration
  output; the MP quantiles of both are printed, with the per-set realizer's speed measured
  on ``--k8-old`` of the sets (its MP there is the bundled one).
- **k = 9.** ``--sample`` sets drawn (seeded) from ``--k9``: a pickle of a dict ID text →
  ``(9, 2)`` float realization, or an ``.npz`` with ``texts`` and ``points`` (the enumeration
  of nine-point order types; one chirality per reflection pair is kept, the one with the
  smaller text). Both realizers on the same sets (the per-set one on a seeded random
  ``--old-sample`` of them when given: it needs one to several CPU seconds per nine-point set).

Printed per realizer: MP quantiles (min, 10 %, median, grid units), sets per CPU second, and
for the shared sets the ratio of MP per set (batched / per set). Every result is checked to
keep its canonical ID (``realize_all`` raises otherwise).
"""

from __future__ import annotations

import argparse
import pickle
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ottag_db.core.canonical import canonical_batch, canonicalize_lambdas, mirror_lambdas
from ottag_db.files.pointfile import read_point_file
from ottag_db.generation.effort import RealizeEffort, default_effort
from ottag_db.generation.objective import grid_mp
from ottag_db.generation.realize import realize_all

#: The per-set realizer as the bundled data were made with it (k = 8) and the batched one.
PER_SET = default_effort(8)
BATCHED = default_effort(9)


def _quantiles(mp: NDArray[np.float64]) -> str:
    q = np.quantile(mp, [0.0, 0.1, 0.5])
    return f"MP min {q[0]:6.3f}  10% {q[1]:6.3f}  median {q[2]:6.3f}"


def _run(
    name: str, points: Sequence[NDArray[np.float64]], texts: list[str], effort: RealizeEffort, seed: int
) -> NDArray[np.float64]:
    k = points[0].shape[0]
    start = time.process_time()
    sets = realize_all(points, texts, seed=seed, efforts={k: effort})
    cpu = time.process_time() - start
    mp = np.array([s.mp for s in sets])
    rate = f"{len(texts) / cpu:7.2f} sets/s ({1000 * cpu / len(texts):7.1f} ms/set)"
    print(f"  {name:<28} {len(texts):6d} sets  {_quantiles(mp)}  {rate}")
    return mp


def _ratio(new: NDArray[np.float64], old: NDArray[np.float64]) -> None:
    r = new / old
    q = np.quantile(r, [0.0, 0.1, 0.5, 0.9])
    print(
        f"  per set, batched / per-set MP: min {q[0]:.3f}  10% {q[1]:.3f}  median {q[2]:.3f}  90% {q[3]:.3f}; "
        f"batched ≥ per-set on {np.mean(r >= 1 - 1e-9):.0%}"
    )


def _eight(seed: int, old_sample: int, data_dir: Path) -> None:
    from ottag_db.generation.enumeration import enumerate_order_types

    print("k = 8 (all order types up to reflection; per-set MP = the bundled file, made with seed 0)")
    start = time.perf_counter()
    reps = sorted((r for r in enumerate_order_types(8)[8] if r.representative), key=lambda r: r.text)
    print(f"  enumeration: {len(reps)} sets in {time.perf_counter() - start:.0f} s wall")
    bundled = read_point_file(data_dir / "ottag-k08.b08", 8).astype(np.float64)
    texts = [r.text for r in reps]
    if canonical_batch(bundled).texts() != texts:
        raise SystemExit("the enumeration does not give the bundled k = 8 order types in the bundled order")
    points = [r.points for r in reps]
    bundled_mp = grid_mp(bundled)
    print(f"  {'per-set (bundled file)':<28} {len(texts):6d} sets  {_quantiles(bundled_mp)}")
    new = _run("batched", points, texts, BATCHED, seed)
    _ratio(new, bundled_mp)
    if old_sample > 0:
        pick = np.sort(np.random.default_rng(seed).choice(len(texts), min(old_sample, len(texts)), replace=False))
        old = _run("per-set (speed sample)", [points[i] for i in pick], [texts[i] for i in pick], PER_SET, seed)
        if seed == 0:
            print(f"  (its MP equals the bundled file's on these sets: {bool(np.allclose(old, bundled_mp[pick]))})")


def _load_nine(path: Path) -> tuple[list[str], NDArray[np.float64]]:
    if path.suffix == ".npz":
        with np.load(path) as data:
            texts = [str(t) for t in data["texts"]]
            points = np.asarray(data["points"], dtype=np.float64)
    else:
        with open(path, "rb") as fh:
            found = pickle.load(fh)
        texts = sorted(found)
        points = np.stack([np.asarray(found[t], dtype=np.float64) for t in texts])
    mirrors = canonicalize_lambdas(mirror_lambdas(canonical_batch(points).lambdas)).texts()
    keep = [i for i, (t, m) in enumerate(zip(texts, mirrors, strict=True)) if t <= m]
    return [texts[i] for i in keep], points[keep]


def _nine(path: Path, sample: int, old_sample: int | None, seed: int) -> None:
    texts, points = _load_nine(path)
    pick = np.sort(np.random.default_rng(seed).choice(len(texts), min(sample, len(texts)), replace=False))
    sub_texts = [texts[i] for i in pick]
    sub_points = [points[i] for i in pick]
    print(f"k = 9 ({len(texts)} order types up to reflection in {path.name}; a seeded sample of {len(pick)})")
    new = _run("batched", sub_points, sub_texts, BATCHED, seed)
    n_old = len(pick) if old_sample is None else min(old_sample, len(pick))
    # A seeded random part of the sample (the sample is in ID order, and its first sets are
    # not typical: low IDs have more collinear-looking structure and smaller MP).
    part = np.sort(np.random.default_rng(seed + 1).choice(len(pick), n_old, replace=False))
    old = _run("per-set", [sub_points[i] for i in part], [sub_texts[i] for i in part], PER_SET, seed)
    if n_old < len(pick):
        print(f"  {'batched, same sets':<28} {n_old:6d} sets  {_quantiles(new[part])}")
    _ratio(new[part], old)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--k9", type=Path, help="nine-point realizations: pickle (dict ID → points) or .npz")
    parser.add_argument("--sample", type=int, default=1000, help="nine-point sets to realize")
    parser.add_argument("--old-sample", type=int, help="of those, how many the per-set realizer gets (default all)")
    parser.add_argument("--k8-old", type=int, default=100, help="eight-point sets for the per-set realizer's speed")
    parser.add_argument("--skip-k8", action="store_true")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--data-dir", type=Path, default=Path(__file__).resolve().parents[1] / "data")
    args = parser.parse_args(argv)
    print("CPU time of this process; both realizers in the same run, one after the other.")
    if not args.skip_k8:
        _eight(args.seed, args.k8_old, args.data_dir)
    if args.k9 is not None:
        _nine(args.k9, args.sample, args.old_sample, args.seed)
    else:
        print("k = 9: skipped (no --k9 file)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
