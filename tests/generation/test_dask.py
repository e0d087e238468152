"""Generation on Dask (issue 14, item 3): a cluster gives the in-process bytes, and an
interrupted run resumes from the batches it finished.

The cluster is a real ``distributed.LocalCluster`` of two worker processes (one thread each),
reached by its scheduler address as ``generate --scheduler`` does.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from ottag_db.app.generating import default_work_dir, file_name, generate_database
from ottag_db.generation.enumeration import enumerate_order_types
from ottag_db.generation.realize import BatchDone, RealizedSet, realize_all


class Interrupt(Exception):
    """Stands for Ctrl-C in the middle of a run."""


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=50
    ) as cluster:
        yield str(cluster.scheduler_address)


@pytest.fixture(scope="module")
def six_point_sets() -> tuple[list[np.ndarray], list[str]]:
    reps = sorted((r for r in enumerate_order_types(6)[6] if r.representative), key=lambda r: r.text)
    return [r.points for r in reps], [r.text for r in reps]


def _same(a: list[RealizedSet], b: list[RealizedSet]) -> bool:
    return len(a) == len(b) and all(
        x.text == y.text and np.array_equal(x.points, y.points) and x.mp == y.mp and x.continuous_mp == y.continuous_mp
        for x, y in zip(a, b, strict=True)
    )


def _assert_same_files(a: Path, b: Path, ks: range) -> None:
    for k in ks:
        assert (a / file_name(k)).read_bytes() == (b / file_name(k)).read_bytes(), f"k = {k}"
    assert (a / "manifest.json").read_bytes() == (b / "manifest.json").read_bytes()


def test_cluster_of_two_workers_writes_the_in_process_files_k6(tmp_path: Path, scheduler: str) -> None:
    here = generate_database(max_k=6, out_dir=tmp_path / "here", seed=0, jobs=1)
    there = generate_database(max_k=6, out_dir=tmp_path / "there", seed=0, scheduler=scheduler)
    _assert_same_files(tmp_path / "here", tmp_path / "there", range(3, 7))
    assert here.records == there.records == {3: 1, 4: 2, 5: 3, 6: 16}
    # The work folders beside the outputs are gone once the files are written.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["here", "there"]


@pytest.mark.slow
def test_cluster_of_two_workers_writes_the_in_process_files_k7(tmp_path: Path, scheduler: str) -> None:
    # About 80 s in process plus 45 s on the cluster on two idle cores.
    generate_database(max_k=7, out_dir=tmp_path / "here", seed=0, jobs=1)
    generate_database(max_k=7, out_dir=tmp_path / "there", seed=0, scheduler=scheduler)
    _assert_same_files(tmp_path / "here", tmp_path / "there", range(3, 8))


def test_interrupted_run_resumes_without_recomputing_finished_batches(
    tmp_path: Path, scheduler: str, six_point_sets: tuple[list[np.ndarray], list[str]]
) -> None:
    points, texts = six_point_sets
    reference = realize_all(points, texts, seed=0)  # in process, nothing kept
    work = tmp_path / "work"

    computed: list[int] = []

    def stop_after_two(b: BatchDone) -> None:
        assert not b.reused
        computed.append(b.index)
        if len(computed) == 2:
            raise Interrupt

    with pytest.raises(Interrupt):  # on the cluster: the other batches are cancelled
        realize_all(points, texts, seed=0, scheduler=scheduler, work_dir=work, on_batch=stop_after_two)
    kept = sorted(work.glob("*.npz"))
    assert len(kept) == 2 and not list(work.glob("*.tmp"))
    stamps = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in kept}

    events: list[BatchDone] = []
    resumed = realize_all(points, texts, seed=0, work_dir=work, on_batch=events.append)
    assert _same(resumed, reference)
    assert sorted(b.index for b in events if b.reused) == sorted(computed)
    assert sorted(b.index for b in events if not b.reused) == sorted(set(range(8)) - set(computed))
    assert sum(b.sets for b in events) == 16
    # The kept files were read, not rewritten.
    assert {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in kept} == stamps
    assert len(list(work.glob("*.npz"))) == 8


def test_a_damaged_or_foreign_batch_file_is_recomputed(
    tmp_path: Path, six_point_sets: tuple[list[np.ndarray], list[str]]
) -> None:
    points, texts = six_point_sets
    work = tmp_path / "work"
    first = realize_all(points[:4], texts[:4], seed=0, work_dir=work)  # 4 batches of 1
    files = sorted(work.glob("*.npz"))
    assert len(files) == 4
    files[0].write_bytes(files[0].read_bytes()[:100])  # truncated, as by a crash mid-write
    events: list[BatchDone] = []
    again = realize_all(points[:4], texts[:4], seed=0, work_dir=work, on_batch=events.append)
    assert _same(first, again)
    reused = {b.index: b.reused for b in events}
    assert reused == {0: False, 1: True, 2: True, 3: True}
    # Another seed hashes to other names: nothing is reused.
    events.clear()
    realize_all(points[:4], texts[:4], seed=1, work_dir=work, on_batch=events.append)
    assert not any(b.reused for b in events)


def test_generate_resumes_after_an_interrupt_and_cleans_up(tmp_path: Path, scheduler: str) -> None:
    out = tmp_path / "out"
    work = default_work_dir(out)
    assert work == (tmp_path / "out.partial").resolve()

    def interrupt_in_k6(stage: str, done: int, total: int) -> None:
        if stage == "realize k=6" and done >= 6:
            raise Interrupt

    with pytest.raises(Interrupt):
        generate_database(max_k=6, out_dir=out, seed=0, scheduler=scheduler, progress=interrupt_in_k6)
    kept = {p.name: p.stat().st_ino for p in work.glob("*.npz")}
    assert {name[:3] for name in kept} == {"k03", "k04", "k05", "k06"}
    assert not (out / "manifest.json").exists()

    seen: list[tuple[str, int, int]] = []
    generate_database(max_k=6, out_dir=out, seed=0, jobs=1, progress=lambda s, d, t: seen.append((s, d, t)))
    assert not work.exists()
    first_k6 = [d for s, d, _ in seen if s == "realize k=6"]
    assert first_k6[:4] == [0, 2, 4, 6]  # the three finished batches come back before any new one
    generate_database(max_k=6, out_dir=tmp_path / "straight", seed=0)
    _assert_same_files(out, tmp_path / "straight", range(3, 7))


def test_cli_options_and_light_start(tmp_path: Path) -> None:
    bad = subprocess.run(
        [sys.executable, "-m", "ottag_db", "generate", "--scheduler", "not an address", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
    )
    assert bad.returncode == 2 and "--scheduler" in bad.stderr and "Traceback" not in bad.stderr
    probe = (
        "import json, sys\n"
        "from ottag_db.cli import main\n"
        "sys.argv = ['ottag-db', 'generate', '--help']\n"
        "try:\n    main()\nexcept SystemExit:\n    pass\n"
        "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules} & {'dask', 'distributed', 'numpy'})),"
        " file=sys.stderr)\n"
    )
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert json.loads(proc.stderr.strip().splitlines()[-1]) == []
    assert "--scheduler" in proc.stdout and "--work-dir" in proc.stdout


def test_generate_with_local_workers_prints_no_dask_log_lines(tmp_path: Path) -> None:
    # A heartbeat that races the local cluster's shutdown used to print Dask's traceback.
    command = [sys.executable, "-m", "ottag_db", "generate", "--max-k", "5", "--jobs", "2", "--quiet"]
    proc = subprocess.run(
        [*command, "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "distributed." not in proc.stderr
    assert "k = 5: 3 order types up to reflection" in proc.stdout
