"""Replay the paper's Sec. 5.1 / 5.2 projection experiments (Tables 5 and 6) on point-set files.

The bundled (and, with ``OTTAG_AICHHOLZER_DIR``, the reference) files of each ``--k``; any
other file with ``--file [K=]PATH``. Nine points beside the paper's k = 7, 8 (the bundled
``ottag-k09.b08``; there is no reference file of nine points here):

    python benchmarks/projection_robustness.py --k 7 8 9 --sample 2000
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.canonical import canonical_batch
from ottag_db.core.geometry import triple_figures
from ottag_db.files.pointfile import read_point_file

__all__ = [
    "PAPER_TABLE5",
    "PAPER_TABLE6",
    "CameraSweep",
    "SweepResult",
    "distance_sweep",
    "project",
    "rotation_sweep",
    "run_sweep",
]

#: Paper's Table 5 (rotation): k → (images, successes).
PAPER_TABLE5: dict[int, tuple[int, int]] = {7: (437_400, 427_437), 8: (10_740_600, 10_093_612)}
#: Paper's Table 6 (distance): k → (images, successes).
PAPER_TABLE6: dict[int, tuple[int, int]] = {7: (128_250, 125_498), 8: (3_149_250, 2_232_380)}

#: Table 4: 640 × 480 image, f_x = f_y = 1000 px, principal point (320, 240), no skew.
FOCAL = 1000.0
PRINCIPAL = (320.0, 240.0)

#: Views per batch of canonicalization (bounds memory to a few hundred MB).
_BATCH_VIEWS = 250_000


@dataclass(frozen=True)
class CameraSweep:
    """A list of camera poses: Euler angles θ1, θ2 (degrees, θ3 = 0) and distances (a.u.)."""

    name: str
    theta1: NDArray[np.float64]
    theta2: NDArray[np.float64]
    distance: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.theta1.size)


def rotation_sweep() -> CameraSweep:
    """Sec. 5.1: θ1 = 0°, 10°, …, 350° × θ2 = 0°, 1°, …, 89° at distance 1000 (3240 views)."""
    t1, t2 = np.meshgrid(np.arange(0.0, 360.0, 10.0), np.arange(0.0, 90.0, 1.0), indexing="ij")
    return CameraSweep("rotation", t1.ravel(), t2.ravel(), np.full(t1.size, 1000.0))


def distance_sweep() -> CameraSweep:
    """Sec. 5.2: θ1 = θ2 = 0 and distance 500, 510, …, 9990 (950 views)."""
    d = np.arange(500.0, 10_000.0, 10.0)
    return CameraSweep("distance", np.zeros(d.size), np.zeros(d.size), d)


def _rotations(theta1_deg: NDArray[np.float64], theta2_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """``R = Rz(θ3) · Ry(θ2) · Rz(θ1)`` with θ3 = 0, as ``(V, 3, 3)``."""
    a = np.deg2rad(theta1_deg)
    b = np.deg2rad(theta2_deg)
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    zero = np.zeros_like(a)
    one = np.ones_like(a)
    rz = np.stack([np.stack([ca, -sa, zero], -1), np.stack([sa, ca, zero], -1), np.stack([zero, zero, one], -1)], 1)
    ry = np.stack([np.stack([cb, zero, sb], -1), np.stack([zero, one, zero], -1), np.stack([-sb, zero, cb], -1)], 1)
    out: NDArray[np.float64] = np.einsum("vij,vjk->vik", ry, rz)
    return out


def project(points: NDArray[np.float64], sweep: CameraSweep) -> NDArray[np.int64]:
    """Pixels ``(B, V, k, 2)`` of ``(B, k, 2)`` sets seen from every pose of ``sweep``.

    Each set is centred on its centroid on the plane z = 0 (its own units are world
    units); the camera ``K [R | t]`` with ``t = (0, 0, d)`` looks at the origin along its
    optical axis from distance ``d``; pixels are ``⌊u + 0.5⌋, ⌊v + 0.5⌋``.
    """
    centred = points - points.mean(axis=1, keepdims=True)
    rot = _rotations(sweep.theta1, sweep.theta2)[:, :, :2]  # z = 0: only the first two columns
    cam = np.einsum("vij,bkj->bvki", rot, centred)
    cam[..., 2] += sweep.distance[None, :, None]
    u = FOCAL * cam[..., 0] / cam[..., 2] + PRINCIPAL[0]
    v = FOCAL * cam[..., 1] / cam[..., 2] + PRINCIPAL[1]
    pix: NDArray[np.int64] = np.floor(np.stack([u, v], axis=-1) + 0.5).astype(np.int64)
    return pix


@dataclass(frozen=True)
class SweepResult:
    """Outcome of one sweep over one file: sets, images, successes and failures per view."""

    sets: int
    images: int
    successes: int
    failures_per_view: NDArray[np.int64]
    failures_per_set: NDArray[np.int64]

    @property
    def rate(self) -> float:
        """Percentage of views whose rounded pixels give the set's own canonical ID."""
        return 100.0 * self.successes / self.images if self.images else float("nan")


def _set_chunks(n_sets: int, n_views: int) -> Iterator[slice]:
    per = max(1, _BATCH_VIEWS // n_views)
    for start in range(0, n_sets, per):
        yield slice(start, min(n_sets, start + per))


def run_sweep(points: NDArray[np.int64], sweep: CameraSweep) -> SweepResult:
    """Count the views of each set whose canonical ID equals the set's ID (fully batched)."""
    pts = points.astype(np.float64)
    n_sets, k, _ = pts.shape
    truth = canonical_batch(pts).lambdas
    n_views = len(sweep)
    successes = 0
    failures = np.zeros(n_views, dtype=np.int64)
    per_set = np.zeros(n_sets, dtype=np.int64)
    for part in _set_chunks(n_sets, n_views):
        pix = project(pts[part], sweep)  # (b, V, k, 2)
        b = pix.shape[0]
        flat = pix.reshape(b * n_views, k, 2)
        # No collinear triple and no repeated point; exact for integer pixels (below 2**26).
        ok = (triple_figures(flat)[0] != 0).all(axis=1)
        same = np.zeros(b * n_views, dtype=bool)
        good = np.flatnonzero(ok)
        if good.size:
            lam = canonical_batch(flat[good].astype(np.float64)).lambdas
            expect = np.repeat(truth[part], n_views, axis=0)[good]
            same[good] = (lam == expect).all(axis=(1, 2))
        successes += int(same.sum())
        failures += (~same).reshape(b, n_views).sum(axis=0)
        per_set[part] = (~same).reshape(b, n_views).sum(axis=1)
    return SweepResult(n_sets, n_sets * n_views, successes, failures, per_set)


def _load(directory: Path, k: int, reference: bool) -> NDArray[np.int64] | None:
    path = directory / (f"otypes{k:02d}.b08" if reference else f"ottag-k{k:02d}.b08")
    if not path.exists():
        return None
    return read_point_file(path, k)


def _file_arg(text: str) -> tuple[int, Path]:
    """``K=PATH`` or ``PATH`` whose name ends in a two-digit point count (``…k09.b08``)."""
    if "=" in text and text.split("=", 1)[0].isdigit():
        k, path = text.split("=", 1)
        return int(k), Path(path)
    m = re.search(r"(\d{2})\.b(08|16)$", text)
    if m is None:
        raise argparse.ArgumentTypeError(f"{text}: give K=PATH (the name does not end in NN.b08)")
    return int(m.group(1)), Path(text)


def _row(label: str, values: list[str]) -> str:
    return f"{label:<28}" + "".join(f"{v:>16}" for v in values)


def main(argv: list[str] | None = None) -> int:
    """Print Tables 5 and 6: paper vs reference files vs the bundled ottag files."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--reference-dir", type=Path, default=os.environ.get("OTTAG_AICHHOLZER_DIR"))
    parser.add_argument("--data-dir", type=Path, default=Path(__file__).resolve().parents[1] / "data")
    parser.add_argument("--k", type=int, nargs="+", default=[7, 8], choices=[3, 4, 5, 6, 7, 8, 9])
    parser.add_argument(
        "--file",
        type=_file_arg,
        action="append",
        default=[],
        help="[K=]PATH: also sweep this point file (e.g. a nine-point file: --k 9 --file …-k09.b08)",
    )
    parser.add_argument("--limit", type=int, default=None, help="only the first N sets of each file")
    parser.add_argument("--sample", type=int, default=None, help="only N sets of each file, evenly spaced")
    args = parser.parse_args(argv)
    files = dict(args.file)
    ks = sorted(set(args.k) | set(files))
    sources: list[tuple[str, Path, bool]] = []
    if args.reference_dir is not None:
        sources.append(("reference", Path(args.reference_dir), True))
    else:
        print("OTTAG_AICHHOLZER_DIR not set: skipping the reference files", file=sys.stderr)
    sources.append(("ottag", args.data_dir, False))
    for table, sweep, paper in (
        ("Table 5 (rotation, d = 1000)", rotation_sweep(), PAPER_TABLE5),
        ("Table 6 (distance 500 … 9990, θ = 0)", distance_sweep(), PAPER_TABLE6),
    ):
        print(f"\n{table}: {len(sweep)} views per set")
        header = []
        lines: dict[str, list[str]] = {"sets": [], "images": [], "successes": [], "success %": []}
        for k in ks:
            if k in paper:
                images, succ = paper[k]
                header.append(f"paper k={k}")
                lines["sets"].append(str(images // len(sweep)))
                lines["images"].append(str(images))
                lines["successes"].append(str(succ))
                lines["success %"].append(f"{100.0 * succ / images:.2f}")
            given = [("file", files[k], False)] if k in files else []
            for name, where, reference in sources + given:
                pts = read_point_file(where, k) if name == "file" else _load(where, k, reference)
                if pts is None:
                    continue
                if args.limit:
                    pts = pts[: args.limit]
                if args.sample and args.sample < len(pts):
                    pts = pts[np.linspace(0, len(pts) - 1, args.sample).round().astype(np.int64)]
                t0 = time.perf_counter()
                res = run_sweep(pts, sweep)
                print(f"  {name} k={k}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
                header.append(f"{name} k={k}")
                lines["sets"].append(str(res.sets))
                lines["images"].append(str(res.images))
                lines["successes"].append(str(res.successes))
                lines["success %"].append(f"{res.rate:.2f}")
        print(_row("", header))
        for label, values in lines.items():
            print(_row(label, values))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
