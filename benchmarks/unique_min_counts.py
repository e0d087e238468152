"""E^k: how many order types of k points have a unique minimal λ-matrix (paper Table 3), k ≤ 9.

Usage:
    python benchmarks/unique_min_counts.py                      # the bundled files (k = 3 … 8, and 9 once bundled)
    python benchmarks/unique_min_counts.py --file otypes09.b08  # one more point file, n from the name
    python benchmarks/unique_min_counts.py --file sets.b16 --points 9
    python benchmarks/unique_min_counts.py --pickle found.pkl   # dict ID text -> (k, 2) float realization

E^k needs no realization on the grid: the unique-minimum flag is a property of the order
type (of its λ-matrix), so any realization of each order type gives it, and one realization
per reflection pair gives the mirror's too (its λ-matrix is n − 2 − λ off the diagonal). For
each input this prints the order types with both chiralities and up to reflection (a chiral
pair once), the achiral ones, and E^k in both conventions — the numbers the importer's
unique-minimum flag gives ``ottag-db stats`` once every order type of k is imported. The
input must hold every order type of k once per reflection pair (a pickle may hold both
chiralities; repeats are counted once).
"""

from __future__ import annotations

import argparse
import pickle
import sys
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ottag_db.core.canonical import canonicalize_lambdas, mirror_lambdas
from ottag_db.core.geometry import lambda_matrices
from ottag_db.core.types import COMPLETE_COUNTS, COMPLETE_COUNTS_UP_TO_REFLECTION
from ottag_db.files.bundled import bundled_files_available
from ottag_db.files.pointfile import inspect_point_file, read_point_file

_CHUNK = 20000


def unique_min_counts(points: NDArray[np.float64]) -> dict[str, int]:
    """Counts over the order types of ``points`` (B, k, 2) and their mirror images."""
    flags: dict[str, bool] = {}
    mirror_of: dict[str, str] = {}
    for s in range(0, points.shape[0], _CHUNK):
        lam = lambda_matrices(points[s : s + _CHUNK])
        own = canonicalize_lambdas(lam)
        mirror = canonicalize_lambdas(mirror_lambdas(lam))
        for text, mtext, m1, m2 in zip(
            own.texts(), mirror.texts(), own.minimal_orderings, mirror.minimal_orderings, strict=True
        ):
            flags[text] = bool(m1 == 1)
            flags[mtext] = bool(m2 == 1)
            mirror_of[text], mirror_of[mtext] = mtext, text
    reps = [t for t in flags if t <= mirror_of[t]]
    return {
        "order_types": len(flags),
        "unique_min": sum(flags.values()),
        "up_to_reflection": len(reps),
        "unique_min_up_to_reflection": sum(flags[t] for t in reps),
        "achiral": sum(1 for t in flags if mirror_of[t] == t),
    }


def _report(label: str, k: int, points: NDArray[np.float64]) -> None:
    start = time.perf_counter()
    c = unique_min_counts(points)
    seconds = time.perf_counter() - start
    full = c["order_types"] == COMPLETE_COUNTS.get(k) and c["up_to_reflection"] == COMPLETE_COUNTS_UP_TO_REFLECTION.get(
        k
    )
    print(
        f"{label}: k = {k}: {c['order_types']} order types ({c['up_to_reflection']} up to reflection, "
        f"{c['achiral']} achiral){'' if full else ' — NOT every order type of k'}; "
        f"E^{k} = {c['unique_min']} with mirrors, {c['unique_min_up_to_reflection']} up to reflection "
        f"({seconds:.1f} s)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--file", type=Path, action="append", default=[], help="A point file (.b08/.b16).")
    parser.add_argument("--points", type=int, default=None, help="Points per record of --file (else from the name).")
    parser.add_argument("--pickle", type=Path, default=None, help="dict ID text -> (k, 2) realization.")
    args = parser.parse_args()
    for path, k, _default in bundled_files_available():
        _report(path.name, k, read_point_file(path, k).astype(np.float64))
    for path in args.file:
        info = inspect_point_file(path, args.points)
        _report(path.name, info.n, read_point_file(path, info.n).astype(np.float64))
    if args.pickle is not None:
        with args.pickle.open("rb") as fh:
            found = pickle.load(fh)  # a trusted local file written by the enumeration
        texts = sorted(found)
        pts = np.stack([np.asarray(found[t], dtype=np.float64) for t in texts])
        _report(args.pickle.name, pts.shape[1], pts)


if __name__ == "__main__":
    main()
