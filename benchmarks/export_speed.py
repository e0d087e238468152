"""Time `ottag-db export --polarity both` of every drawable tag (k ≤ 8, both chiralities) at 40 mm.

Builds a fresh database from the bundled data (``import`` stores every layout and placement,
so its time includes them; export only reads them), then writes the full two-polarity sheet
and prints seconds, tags and pages. Target on the 2-core machine: under 60 s for the sheet.

Usage: python benchmarks/export_speed.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from click.testing import CliRunner

from ottag_db.cli import cli


def main() -> None:
    runner = CliRunner()
    with tempfile.TemporaryDirectory() as tmp:
        db = str(Path(tmp) / "db.sqlite")
        t = time.perf_counter()
        res = runner.invoke(cli, ["import", "--db", db, "--quiet"])
        assert res.exit_code == 0, res.output
        print(f"import bundled data, layouts and placements included: {time.perf_counter() - t:.1f} s")
        out = Path(tmp) / "all.pdf"
        t = time.perf_counter()
        args = ["export", "--db", db, "--quiet", "--polarity", "both", "--tag-size", "40mm", str(out)]
        res = runner.invoke(cli, args)
        elapsed = time.perf_counter() - t
        assert res.exit_code == 0, res.output
        print(f"export --polarity both --tag-size 40mm: {elapsed:.1f} s (target < 60 s)")
        print(f"  {res.stdout.strip()}")
        print(f"  {out.stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
