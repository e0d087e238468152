"""The k = 9 flip graph and a flip-distance-2 nine-point dictionary: size, MP distribution, cost.

Usage:
    ottag-db import --db k9.sqlite && ottag-db import --db k9.sqlite --k 9
    python benchmarks/dictionary_k9.py k9.sqlite [--name d2k9] [--k 9] [--min-flip-distance 2]

Works on a copy of the database (the original is left as it is) that holds every order type
of k points. It computes and stores the flip graph of k (as ``dictionary create`` does the first
time), then creates the dictionary as ``ottag-db dictionary create NAME --k K`` would, and prints:
the graph's edges (directed, as stored) and the bytes it adds to the SQLite file, the time of
each step, the dictionary's size (with the unique-minimum members), and how many members have
MP ≥ v for the paper's Table 7 thresholds (grid units, the realization each tag is printed
from) beside the same counts for all order types of k.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ottag_db.core.types import MP_THRESHOLDS
from ottag_db.store.db import open_database
from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary
from ottag_db.store.flipgraph import ensure_flip_graph
from ottag_db.store.queries import database_stats


def _size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.parent.glob(path.name + "*"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("db", type=Path)
    parser.add_argument("--name", default="d2k9")
    parser.add_argument("--k", type=int, default=9)
    parser.add_argument("--min-flip-distance", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(dir=args.db.parent) as tmp:
        path = Path(tmp) / args.db.name
        shutil.copy(args.db, path)
        db = open_database(path)
        try:
            with db.engine.connect() as conn:
                conn.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)")
            before = _size(path)
            start = time.perf_counter()
            edges = ensure_flip_graph(db, [args.k])[args.k]
            graph_s = time.perf_counter() - start
            with db.engine.connect() as conn:
                conn.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)")
            added = _size(path) - before
            print(
                f"flip graph k = {args.k}: {edges} directed edges ({edges // 2} pairs), {graph_s:.1f} s, "
                f"+{added / 1e6:.1f} MB in the SQLite file ({before / 1e6:.1f} MB before)"
            )
            start = time.perf_counter()
            info = create_dictionary(
                db, args.name, DictionaryOptions(ks=(args.k,), min_flip_distance=args.min_flip_distance)
            )
            dict_s = time.perf_counter() - start
            mp = np.array([m.mp for m in info.members])
            unique = sum(m.unique_min for m in info.members)
            print(
                f"dictionary {args.name} (k = {args.k}, D = {args.min_flip_distance}): {len(info.members)} tags, "
                f"{unique} with a unique minimum, {dict_s:.1f} s; MP min {mp.min():.3f}, median "
                f"{np.median(mp):.3f}, max {mp.max():.3f} (grid units)"
            )
            every = next(s for s in database_stats(db) if s.k == args.k)
            print(f"v     members with MP >= v   all {every.order_types} order types of k = {args.k}")
            for v in MP_THRESHOLDS:
                print(f"{v:<5.1f} {int((mp >= v).sum()):>22}   {every.mp_at_least[v]:>8}")
        finally:
            db.close()


if __name__ == "__main__":
    main()
