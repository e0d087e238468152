"""Canonical IDs per second for n = 8, 9, 10 and peak memory of importing a large n = 10 file.

Writes synthetic random point sets (16-bit coordinates, general position) as .b16 files in
a temporary folder, then
1. streams each file through the canonicalizer (λ-matrices, canonical orderings, minimum,
   labeling) and prints sets/s;
2. imports n = 10 files of 250 000 and 1 000 000 records with `ottag-db import` in a fresh
   process and prints the peak resident memory of each (it must not grow with the file).

Usage: python benchmarks/canonical_ids.py [--records 200000] [--import-records 1000000]
Target on the 2-core machine: >= 100 000 sets/s for n = 10.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ottag_db.core.canonical import canonical_batch
from ottag_db.core.geometry import general_position_mask
from ottag_db.files.pointfile import inspect_point_file, iter_point_chunks, write_point_file


def make_file(path: Path, n: int, records: int, seed: int) -> None:
    """Random 16-bit point sets in general position (rare degenerate sets are redrawn)."""
    rng = np.random.default_rng(seed)
    out = []
    left = records
    while left > 0:
        batch = rng.integers(0, 65536, size=(min(left, 20_000), n, 2))
        batch = batch[general_position_mask(batch)]
        out.append(batch)
        left -= batch.shape[0]
    write_point_file(path, np.concatenate(out)[:records])


def canonical_rate(path: Path, n: int) -> tuple[float, float]:
    info = inspect_point_file(path, n)
    t = time.perf_counter()
    count = 0
    for _, pts in iter_point_chunks(info, chunk_records=16384):
        canonical_batch(pts)
        count += pts.shape[0]
    dt = time.perf_counter() - t
    return count / dt, dt


def import_peak_memory(path: Path, n: int, db: Path) -> tuple[float, float]:
    code = (
        "import sys, time\n"
        "from ottag_db.cli import cli\n"
        "t = time.perf_counter()\n"
        "try:\n"
        f"    args = ['import', '--quiet', '--points', '{n}', '--db', {str(db)!r}, {str(path)!r}]\n"
        "    cli(args, standalone_mode=False)\n"
        "finally:\n"
        "    print('TIME', time.perf_counter() - t, file=sys.stderr)\n"
        "    hwm = [x for x in open('/proc/self/status') if x.startswith('VmHWM')][0].split()[1]\n"
        "    print('PEAK', hwm, file=sys.stderr)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    lines = dict(line.split(" ", 1) for line in proc.stderr.splitlines() if line[:4] in ("TIME", "PEAK"))
    return float(lines["PEAK"]) / 1024.0, float(lines["TIME"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--records", type=int, default=200_000, help="sets per n for the rate test")
    ap.add_argument("--import-records", type=int, default=1_000_000, help="records of the big n = 10 import")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print(f"canonical IDs per second ({args.records} random sets each, 16-bit coordinates, .b16 files)")
        for n in (8, 9, 10):
            f = folder / f"random{n:02d}.b16"
            make_file(f, n, args.records, seed=n)
            rate, dt = canonical_rate(f, n)
            print(f"  n = {n:2d}: {rate:10,.0f} sets/s  ({dt:.2f} s)")
            if n == 10:
                print(f"  projected for the 14 309 547-set n = 10 file: {14_309_547 / rate / 60:.1f} min")
        print("peak memory of `ottag-db import` of n = 10 .b16 files (fresh process each)")
        for records in sorted({args.import_records // 4, args.import_records}):
            f = folder / f"import{records}.b16"
            make_file(f, 10, records, seed=records)
            peak, seconds = import_peak_memory(f, 10, folder / f"db{records}.sqlite")
            size = f.stat().st_size / 1e6
            print(
                f"  {records:>9,} records ({size:6.1f} MB): peak RSS {peak:7.1f} MB, "
                f"{seconds:6.1f} s ({records / seconds:,.0f} records/s)"
            )
            os.remove(f)


if __name__ == "__main__":
    main()
