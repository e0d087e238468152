"""Layout and placement throughput at import: sets per second, k = 9 beside the bundled k = 8.

What ``import`` computes per realization besides its ID: the triangle layout
(:func:`~ottag_db.core.layout.compute_layouts`), the placement
(:func:`~ottag_db.core.placement.tag_placements`) and the printed MP of the placed points.
Peer in the same run: the placement searched over every edge (the search before edge
pruning; the maps must be identical). Prints wall and CPU rates; on a machine shared with
other work the CPU rate is the steadier one.

    python benchmarks/layout_speed.py [--file data/ottag-k09.b08] [--sets 6000] [--mirrors]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

import ottag_db.core.placement as placement
from ottag_db.core.geometry import maximal_perturbations
from ottag_db.core.layout import compute_layouts
from ottag_db.files.pointfile import read_point_file


def _rate(label: str, n: int, fn: Callable[[], object]) -> object:
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    w, c = time.perf_counter() - w0, time.process_time() - c0
    print(f"  {label:<34} {n / w:>9.0f} sets/s wall {n / c:>9.0f} sets/s CPU  ({w:.1f} s)")
    return out


def _run(name: str, pts: NDArray[np.float64]) -> None:
    n = len(pts)
    print(f"{name}: {n} sets of {pts.shape[1]} points")
    layouts = _rate("layouts", n, lambda: compute_layouts(pts))
    maps = _rate("placements", n, lambda: placement.tag_placements(pts))
    _rate("printed MP", n, lambda: maximal_perturbations(placement.apply_placements(maps, pts)))  # type: ignore[arg-type]
    kept = placement._KEPT_EDGES
    placement._KEPT_EDGES = 10**6  # the peer: every edge scored
    try:
        full = _rate("placements, every edge (peer)", n, lambda: placement.tag_placements(pts))
    finally:
        placement._KEPT_EDGES = kept
    assert np.array_equal(full, maps), "pruned placement differs from the exhaustive one"  # type: ignore[arg-type]
    sizes = np.bincount([lay.size for lay in layouts])  # type: ignore[attr-defined]
    print(f"  triangles per layout: {dict((i, int(c)) for i, c in enumerate(sizes) if c)}; maps identical to peer")


def main(argv: list[str] | None = None) -> int:
    """Print the rates."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--file",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "data" / "ottag-k09.b08",
        help="nine-point file",
    )
    parser.add_argument("--sets", type=int, default=6000, help="first N sets of each file")
    parser.add_argument("--mirrors", action="store_true", help="add the mirror images, as import --with-mirrors")
    parser.add_argument("--data-dir", type=Path, default=Path(__file__).resolve().parents[1] / "data")
    args = parser.parse_args(argv)
    for k, path in ((8, args.data_dir / "ottag-k08.b08"), (9, args.file)):
        pts = read_point_file(path, k)[: args.sets].astype(np.float64)
        if args.mirrors:
            pts = np.concatenate([pts, pts * np.array([-1.0, 1.0]) + np.array([255.0, 0.0])])
        _run(f"k = {k} ({path.name})", pts)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
