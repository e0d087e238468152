"""Use case ``ottag-db generate``: re-create the bundled data from scratch.

Combines :mod:`ottag_db.generation` (enumerate every order type, realize each on the 8-bit grid
with maximal MP) with :mod:`ottag_db.files` (write ``ottag-kNN.b08`` and ``manifest.json``).
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.types import MP_THRESHOLDS, StageProgress
from ottag_db.errors import OttagError, UsageError
from ottag_db.files.bundled import DEFAULT_IMPORT_MAX_K, bundled_manifest
from ottag_db.files.pointfile import file_sha256, read_point_file, write_point_file
from ottag_db.files.resources import data_dir
from ottag_db.generation.enumeration import (
    ENUMERATION_MAX_K,
    FROM_SCRATCH_MAX_K,
    EnumerationPass,
    enumerate_order_types,
    extend_order_types,
)

__all__ = ["BundledComparison", "GenerationReport", "default_work_dir", "file_name", "generate_database"]


@dataclass(frozen=True)
class BundledComparison:
    """How one generated file compares with the bundled file of the same k.

    - ``identical``: the files are byte-identical;
    - ``differing``: records whose points differ (0 when identical);
    - ``records``: records of the generated file.
    """

    identical: bool
    differing: int
    records: int


@dataclass(frozen=True)
class GenerationReport:
    """Summary of :func:`generate_database`.

    - ``records``: ``{k: sets in the file}`` (one per reflection pair);
    - ``with_mirrors``: ``{k: order types counting both chiralities}``;
    - ``achiral``: ``{k: order types equal to their mirror image}`` (``records`` − ``achiral``
      pairs are chiral);
    - ``passes``: ``{k: the enumeration's passes}`` (how many realizations each took);
    - ``files``: ``{k: path of ottag-kNN.b08}``; ``manifest``: path of manifest.json;
    - ``mp_thresholds``: the values v (grid units) of ``mp_table``;
    - ``mp_table``: ``{k: (number of sets with MP ≥ v for each v)}`` (paper's Table 7);
    - ``mp_min``: ``{k: smallest MP of the file}`` (grid units);
    - ``seed``; ``seconds``: wall time per stage ("enumerate", "realize", "total");
    - ``bundled``: ``{k: BundledComparison}`` with the bundled data when ``seed`` is the
      bundled seed (empty otherwise, or without bundled data).
    """

    records: dict[int, int]
    with_mirrors: dict[int, int]
    achiral: dict[int, int]
    passes: dict[int, tuple[EnumerationPass, ...]]
    files: dict[int, Path]
    manifest: Path
    mp_thresholds: tuple[float, ...]
    mp_table: dict[int, tuple[int, ...]]
    mp_min: dict[int, float]
    seed: int
    seconds: dict[str, float]
    bundled: dict[int, BundledComparison]


def _tool_version() -> str:
    """``ottag_db.__version__`` if the package defines it, else "0.1.0"."""
    # Read from sys.modules: generation may not import the package root (import direction),
    # and the root is always imported before one of its sub-packages.
    version = getattr(sys.modules.get("ottag_db"), "__version__", None)
    return version if isinstance(version, str) else "0.1.0"


def file_name(k: int) -> str:
    """Name of the bundled point-set file of ``k`` points.

    Parameters
    ----------
    k : int
        Number of points.

    Returns
    -------
    str
        ``ottag-kNN.b08``.
    """
    return f"ottag-k{k:02d}.b08"


def default_work_dir(out_dir: Path) -> Path:
    """The folder beside ``out_dir`` where :func:`generate_database` keeps finished batches.

    Parameters
    ----------
    out_dir : Path
        The output folder.

    Returns
    -------
    Path
        ``OUT.partial`` next to ``OUT`` (absolute).
    """
    out = Path(out_dir).resolve()
    return out.with_name(f"{out.name or 'out'}.partial")


def generate_database(
    max_k: int = 8,
    out_dir: Path = Path("data"),
    seed: int = 0,
    jobs: int = 1,
    progress: StageProgress | None = None,
    *,
    scheduler: str | None = None,
    work_dir: Path | None = None,
) -> GenerationReport:
    """Enumerate all order types of 3 … ``max_k`` points, realize each reflection pair on the
    [0, 255]² grid with a large MP and write ``ottag-kNN.b08`` plus ``manifest.json``.

    Each file holds one set per reflection pair (the chirality whose ID text is smaller),
    sorted by that ID text: a drop-in replacement of the reference ``otypesNN.b08``. The
    output depends only on ``seed``: not on the workers (``jobs`` local Dask worker processes
    or the cluster at ``scheduler``), and a file does not depend on ``max_k`` either; two
    runs with the same seed write byte-identical files on the same platform. Across machines
    the continuous stage's floating point (SciPy's SLSQP on OpenBLAS, NumPy's SIMD
    functions) follows the CPU's instruction set and the library builds, so another platform
    may realize some sets differently;
    ``bundled`` in the report says whether each file equals the bundled one.
    ``progress(stage, done, total)`` reports the stages ("enumerate k=…", "realize k=…",
    "write").

    **Resumable:** every finished batch of sets is kept in ``work_dir`` (default
    :func:`default_work_dir`); after an interrupt the same call skips them (a realize bar then
    starts where the last run stopped). The batch files are deleted once the files are
    written.

    Parameters
    ----------
    max_k : int, optional
        Largest number of points, 3 … 9 (k = 9: 158,817 sets up to reflection, see README).
    out_dir : Path, optional
        Folder to write into (created when missing).
    seed : int, optional
        Run seed of the realization.
    jobs : int, optional
        Worker processes (≥ 1): the enumeration's process pool and, when above 1, a local
        Dask cluster of ``jobs`` workers (one thread each) for the realization.
    progress : StageProgress, optional
        ``progress(stage, done, total)``.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``) whose workers (with
        ottag-db installed) realize the sets instead of a local cluster.
    work_dir : Path, optional
        Folder for finished batches; :func:`default_work_dir` of ``out_dir`` when None.

    Returns
    -------
    GenerationReport
        Counts, paths, the MP table (grid units) and timings (seconds).

    Raises
    ------
    UsageError
        For ``max_k`` outside 3 … 9 or ``jobs < 1``.
    ClusterError
        When ``scheduler`` cannot be reached.
    """
    if not 3 <= max_k <= ENUMERATION_MAX_K:
        raise UsageError(f"max_k must be between 3 and {ENUMERATION_MAX_K}, got {max_k}")
    if jobs < 1:
        raise UsageError(f"jobs must be at least 1, got {jobs}")
    # Imported here: the realization needs SciPy, which `import ottag_db.generation.database`
    # (e.g. by the CLI at start-up) should not load.
    from ottag_db.generation.checkpoint import BatchStore
    from ottag_db.generation.parallel import Workers, open_workers
    from ottag_db.generation.realize import realize_all

    out = Path(out_dir)
    bundled = _bundled_records(seed, list(range(3, max_k + 1)))
    out.mkdir(parents=True, exist_ok=True)
    work = Path(work_dir) if work_dir is not None else default_work_dir(out)
    realized: dict[int, NDArray[np.int64]] = {}
    mps: dict[int, NDArray[np.float64]] = {}
    start = time.perf_counter()
    # Workers first: an unreachable scheduler fails before the enumeration, not after it.
    enumerate_seconds = 0.0
    with open_workers(Workers(jobs=jobs, scheduler=scheduler)) as runner:
        t0 = time.perf_counter()
        passes: list[EnumerationPass] = []
        types = enumerate_order_types(
            min(max_k, FROM_SCRATCH_MAX_K), progress=progress, jobs=jobs, on_pass=passes.append
        )
        enumerate_seconds += time.perf_counter() - t0
        for k in range(3, max_k + 1):
            if k > FROM_SCRATCH_MAX_K:
                # Nine points start from the grid realizations just made (the ottag-k08.b08
                # records): from the enumeration's float ones the sampled passes miss one pair.
                t0 = time.perf_counter()
                types[k] = extend_order_types(
                    k, realized[k - 1].astype(np.float64), progress, jobs, on_pass=passes.append
                )
                enumerate_seconds += time.perf_counter() - t0
            reps = sorted((r for r in types[k] if r.representative), key=lambda r: r.text)
            sets = realize_all(
                [r.points for r in reps],
                [r.text for r in reps],
                seed=seed,
                runner=runner,
                work_dir=work,
                progress=progress,
                stage=f"realize k={k}",
            )
            realized[k] = np.stack([s.points for s in sets])
            mps[k] = np.array([s.mp for s in sets])
    t2 = time.perf_counter()
    ks = list(range(3, max_k + 1))
    if progress is not None:
        progress("write", 0, len(ks))
    files: dict[int, Path] = {}
    entries: dict[str, dict[str, object]] = {}
    for n, k in enumerate(ks, start=1):
        path = out / file_name(k)
        write_point_file(path, realized[k], bits=8)
        files[k] = path
        entries[str(k)] = {
            "file": path.name,
            "points": k,
            "records": int(realized[k].shape[0]),
            "order_types_with_mirrors": len(types[k]),
            "sha256": file_sha256(path),
            "mp_min": round(float(mps[k].min()), 6),
            "mp_median": round(float(np.median(mps[k])), 6),
            # Nine-point data is large (a minute to import with mirrors): imported on request.
            "default": k <= DEFAULT_IMPORT_MAX_K,
        }
        if progress is not None:
            progress("write", n, len(ks))
    table = {k: tuple(int((mps[k] >= v).sum()) for v in MP_THRESHOLDS) for k in ks}
    manifest = {
        "format": "ottag-db order-type point sets",
        "tool": "ottag-db",
        "version": _tool_version(),
        "seed": seed,
        "grid": [0, 255],
        "description": (
            "One integer realization per order type and reflection pair (the chirality with "
            "the smaller canonical ID text), sorted by that ID; .b08 records of k (x, y) uint8 "
            "points. MP is half the smallest distance from a point to a line through two others."
        ),
        "files": entries,
        "mp_summary": {
            "thresholds": list(MP_THRESHOLDS),
            "counts_at_least": {str(k): list(table[k]) for k in ks},
        },
    }
    manifest_path = out / "manifest.json"
    manifest_path.write_text(json.dumps(manifest, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    BatchStore(work).clear()
    t3 = time.perf_counter()
    return GenerationReport(
        records={k: int(realized[k].shape[0]) for k in ks},
        with_mirrors={k: len(types[k]) for k in ks},
        achiral={k: sum(1 for r in types[k] if r.text == r.mirror_text) for k in ks},
        passes={k: tuple(p for p in passes if p.k == k) for k in ks},
        files=files,
        manifest=manifest_path,
        mp_thresholds=MP_THRESHOLDS,
        mp_table=table,
        mp_min={k: float(mps[k].min()) for k in ks},
        seed=seed,
        seconds={"enumerate": enumerate_seconds, "realize": t2 - start - enumerate_seconds, "total": t3 - start},
        bundled=_compare_bundled(realized, bundled),
    )


def _bundled_records(seed: int, ks: list[int]) -> dict[int, NDArray[np.int64]]:
    """The bundled records of each k, read before anything is written (``--out`` may be the
    bundled folder itself); {} for another seed than the bundled one or without bundled data."""
    try:
        manifest = bundled_manifest()
    except OttagError:
        return {}
    files = manifest.get("files")
    if manifest.get("seed") != seed or not isinstance(files, dict):
        return {}
    out: dict[int, NDArray[np.int64]] = {}
    for k in ks:
        entry = files.get(str(k))
        if not isinstance(entry, dict):
            continue
        try:
            out[k] = read_point_file(data_dir() / str(entry.get("file", file_name(k))), k)
        except OttagError:
            continue
    return out


def _compare_bundled(
    realized: dict[int, NDArray[np.int64]], bundled: dict[int, NDArray[np.int64]]
) -> dict[int, BundledComparison]:
    """Each generated file's records against the bundled ones of the same k."""
    out: dict[int, BundledComparison] = {}
    for k, points in realized.items():
        theirs = bundled.get(k)
        if theirs is None:
            continue
        if theirs.shape == points.shape:
            differing = int((theirs != points).any(axis=(1, 2)).sum())
        else:
            differing = max(int(points.shape[0]), int(theirs.shape[0]))
        out[k] = BundledComparison(identical=differing == 0, differing=differing, records=int(points.shape[0]))
    return out
