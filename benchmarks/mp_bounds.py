"""How far can MP go? Heavy multi-start search on the bundled sets that miss an MP target.

Usage: python benchmarks/mp_bounds.py [--k 7 8] [--seed 1]

For every bundled set of k points whose MP is below the issue's target for that k
(k = 7: 6.0, which covers the 4.0 target too; k = 8: 2.0), this reruns the realizer
with far more effort than ``ottag-db generate`` spends: 20 starts from the bundled points and
random projective images of them, 40 perturbation hops, 60 starts from uniformly random
points in the box, 64 roundings of which 6 are searched, and 8 sub-pixel variants rounded in all
4^k ways. It prints, per set, the bundled MP, the best continuous MP found (in the
[0, 255]² box; rounding to the grid can only lose) and the best integer MP found, then
how many sets stay below each target however hard we search.

A continuous optimum below the target means the target cannot be met by any realization on
the 256 × 256 grid, as far as this (non-exhaustive, multi-start) search can tell.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ottag_db.core.canonical import canonical_batch
from ottag_db.core.geometry import maximal_perturbations
from ottag_db.errors import OttagError
from ottag_db.files.pointfile import read_point_file
from ottag_db.generation.effort import RealizeEffort
from ottag_db.generation.realize import realize_all

#: The targets of issue #3: k → the MP thresholds that must hold for every set / many sets.
TARGETS: dict[int, tuple[float, ...]] = {7: (4.0, 6.0), 8: (2.0,)}

HEAVY = RealizeEffort(
    starts=20,
    hops=40,
    roundings=64,
    searched_roundings=6,
    hard_below=np.inf,
    hard_starts=60,
    exact_variants=8,
    exact_keep=4,
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--k", type=int, nargs="+", default=[7, 8], choices=sorted(TARGETS))
    parser.add_argument("--data-dir", type=Path, default=Path(__file__).resolve().parents[1] / "data")
    parser.add_argument("--seed", type=int, default=1, help="another seed than the bundled data's (0)")
    args = parser.parse_args(argv)
    for k in args.k:
        try:
            pts = read_point_file(args.data_dir / f"ottag-k{k:02d}.b08", k)
        except OttagError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 1
        mps = maximal_perturbations(pts)
        cut = max(TARGETS[k])
        idx = np.flatnonzero(mps < cut)
        texts = canonical_batch(pts[idx].astype(np.float64)).texts()
        print(f"\nk = {k}: {len(idx)} of {len(pts)} bundled sets have MP < {cut}")
        print(f"{'record':>7} {'bundled':>9} {'continuous':>11} {'integer':>9} {'s':>5}")
        conts: list[float] = []
        ints: list[float] = []
        for rec, text in zip(idx.tolist(), texts, strict=True):
            t0 = time.perf_counter()
            one = realize_all([pts[rec]], [text], seed=args.seed, efforts={k: HEAVY})[0]
            best_int = max(one.mp, float(mps[rec]))
            conts.append(one.continuous_mp)
            ints.append(best_int)
            print(
                f"{rec:>7} {mps[rec]:>9.3f} {one.continuous_mp:>11.3f} {best_int:>9.3f} "
                f"{time.perf_counter() - t0:>5.0f}",
                flush=True,
            )
        c = np.asarray(conts)
        i = np.asarray(ints)
        for target in TARGETS[k]:
            above_bundled = int((mps >= target).sum())
            print(
                f"MP >= {target}: bundled {above_bundled}/{len(pts)}; "
                f"continuous optimum below {target} for {int((c < target).sum())} sets "
                f"(at most {len(pts) - int((c < target).sum())} can reach it); "
                f"integer sets found >= {target}: {above_bundled + int(((i >= target) & (mps[idx] < target)).sum())}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
