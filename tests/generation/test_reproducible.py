"""Reproducible generation: seed 0 re-creates the bundled files byte for byte, whatever
``--jobs`` and ``--max-k`` (issue 11, item 7).

The comparison with ``data/`` holds on the platform the bundled data were made on (x86-64
with AVX-512, NumPy 2.4 with its AVX-512 kernels, SciPy 1.17, OpenBLAS with its AVX2 kernels);
elsewhere the continuous optimization may round differently (see README, "The bundled
database"). The runs compared with ``data/`` are ``ottag-db generate`` subprocesses with
OpenBLAS's kernels pinned (``OPENBLAS_CORETYPE=Haswell``): on a CPU with AVX-512 OpenBLAS 0.3.31
picks its SkylakeX kernels, and 7 of the 16 six-point and 55 of the 135 seven-point records differ.
"""

from __future__ import annotations

import functools
import importlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ottag_db.app.generating import file_name, generate_database
from ottag_db.files.bundled import bundled_manifest
from ottag_db.files.pointfile import file_sha256, read_point_file
from ottag_db.files.resources import data_dir
from ottag_db.generation.continuous import _blas_controls, _single_blas_thread
from ottag_db.generation.effort import RealizeEffort
from ottag_db.generation.enumeration import enumerate_order_types
from ottag_db.generation.realize import chunk_size, realize_all

#: OpenBLAS's kernels as when the bundled data were made (read when OpenBLAS loads: set for the
#: ``generate`` subprocesses whose files are compared with ``data/``).
_PINNED_BLAS = {"OPENBLAS_CORETYPE": "Haswell"}
#: Prints the kernel names of the OpenBLAS libraries NumPy and SciPy load.
_BLAS_CORES = """
import ctypes, re, numpy, scipy.optimize
paths = sorted(set(re.findall(r"(/\\S*openblas\\S*\\.so\\S*)", open("/proc/self/maps").read())))
for path in paths:
    lib = ctypes.CDLL(path)
    for name in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename"):
        get = getattr(lib, name, None)
        if get is not None:
            get.restype = ctypes.c_char_p
            print(get().decode())
            break
"""


@functools.cache
def _platform_difference() -> str | None:
    """Why this platform may round differently from the one that made ``data/`` (None if alike),
    with OpenBLAS's kernels pinned as :func:`_generate` pins them."""
    import scipy

    cpu_features = importlib.import_module("numpy._core._multiarray_umath").__cpu_features__
    if np.__version__.split(".")[:2] != ["2", "4"]:
        return f"NumPy {np.__version__} (the bundled data were made with 2.4)"
    if scipy.__version__.split(".")[:2] != ["1", "17"]:
        return f"SciPy {scipy.__version__} (the bundled data were made with 1.17)"
    if not cpu_features.get("X86_V4"):
        return "NumPy runs without its AVX-512 kernels (the bundled data were made with them)"
    probe = subprocess.run(
        [sys.executable, "-c", _BLAS_CORES],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, **_PINNED_BLAS},
    )
    cores = probe.stdout.split()
    if not cores or any(core != _PINNED_BLAS["OPENBLAS_CORETYPE"] for core in cores):
        return f"OpenBLAS does not run its Haswell kernels here (kernels: {', '.join(cores) or 'unknown'})"
    return None


def _generate(out: Path, max_k: int, jobs: int, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``ottag-db generate`` (seed 0) in a subprocess with OpenBLAS's kernels pinned."""
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "ottag_db",
            "generate",
            "--quiet",
            "--max-k",
            str(max_k),
            "--jobs",
            str(jobs),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, **_PINNED_BLAS, **(env or {})},
    )


def _assert_same_as_bundled(out: Path, ks: range) -> None:
    why = _platform_difference()
    if why is not None:
        pytest.skip(f"byte identity with data/ is promised per platform: {why}")
    manifest = bundled_manifest()
    for k in ks:
        ours = (out / file_name(k)).read_bytes()
        bundled = (data_dir() / file_name(k)).read_bytes()
        if ours != bundled:
            a = read_point_file(out / file_name(k), k)
            b = read_point_file(data_dir() / file_name(k), k)
            bad = np.flatnonzero((a != b).any(axis=(1, 2)))
            pytest.fail(f"k = {k}: records {bad.tolist()[:20]} of {len(b)} differ from {file_name(k)}")
        assert file_sha256(out / file_name(k)) == manifest["files"][str(k)]["sha256"]


def test_seed0_k6_is_the_same_for_jobs_1_and_2_and_equals_bundled(tmp_path: Path) -> None:
    reps = {jobs: generate_database(max_k=6, out_dir=tmp_path / f"j{jobs}", seed=0, jobs=jobs) for jobs in (1, 2)}
    for k in range(3, 7):
        assert (tmp_path / "j1" / file_name(k)).read_bytes() == (tmp_path / "j2" / file_name(k)).read_bytes()
    assert reps[1].manifest.read_bytes() == reps[2].manifest.read_bytes()
    # with OpenBLAS's kernels as when the bundled data were made: byte-identical to them
    proc = _generate(tmp_path / "pinned", 6, 1)
    assert proc.returncode == 0, proc.stderr
    _assert_same_as_bundled(tmp_path / "pinned", range(3, 7))
    assert proc.stdout.count("identical to the bundled file") == 4


def test_jobs2_spreads_small_runs_over_processes() -> None:
    # The 16 six-point sets are cut into 8 units, so --jobs 2 really runs worker processes
    # in the test above; the unit size depends on the number of sets only.
    assert chunk_size(16) == 2
    assert chunk_size(135) == 17
    assert chunk_size(3315) == 24
    assert chunk_size(1) == 1


def test_result_of_a_set_does_not_depend_on_its_chunk() -> None:
    reps = [r for r in enumerate_order_types(6)[6] if r.representative]
    pts = [r.points for r in reps]
    texts = [r.text for r in reps]
    effort = {6: RealizeEffort(starts=2, hops=2, roundings=8, searched_roundings=2)}
    together = realize_all(pts, texts, seed=3, efforts=effort)
    alone = [realize_all([p], [t], seed=3, efforts=effort)[0] for p, t in zip(pts[:4], texts[:4], strict=True)]
    reversed_ = realize_all(pts[::-1], texts[::-1], seed=3, jobs=2, efforts=effort)[::-1]
    for a, b in zip(together, reversed_, strict=True):
        assert a.text == b.text and np.array_equal(a.points, b.points) and a.mp == b.mp
    for a, b in zip(together[:4], alone, strict=True):
        assert np.array_equal(a.points, b.points) and a.mp == b.mp


def test_blas_single_thread_in_process() -> None:
    controls = _blas_controls()
    assert controls, "OpenBLAS of NumPy/SciPy not found"
    before = [get() for get, _ in controls]
    with _single_blas_thread():
        assert [get() for get, _ in controls] == [1] * len(controls)
    assert [get() for get, _ in controls] == before


def test_cli_reports_identical_to_bundled(tmp_path: Path) -> None:
    why = _platform_difference()
    if why is not None:
        pytest.skip(f"byte identity with data/ is promised per platform: {why}")
    proc = _generate(tmp_path, 5, 2)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("identical to the bundled file") == 3
    assert "differs" not in proc.stdout and "note:" not in proc.stderr


def test_cli_says_which_files_differ_on_another_instruction_set(tmp_path: Path) -> None:
    # NumPy without its AVX-512 kernels (as on an AVX2-only CPU) rounds arctan2 & co.
    # differently: some six-point sets are realized differently, and generate says so.
    why = _platform_difference()
    if why is not None:
        pytest.skip(f"needs the platform of the bundled data: {why}")
    proc = _generate(tmp_path, 6, 1, {"NPY_DISABLE_CPU_FEATURES": "AVX512_ICL,X86_V4"})
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert "k = 5:" in lines[2] and "identical to the bundled file" in lines[2]
    assert "k = 6:" in lines[3] and "differs from the bundled file in" in lines[3] and "of 16 records" in lines[3]
    note = [line for line in proc.stderr.splitlines() if line.startswith("note:")]
    assert len(note) == 1 and "instruction set" in note[0]


def test_other_seed_is_not_compared(tmp_path: Path) -> None:
    rep = generate_database(max_k=4, out_dir=tmp_path, seed=5)
    assert rep.bundled == {}


@pytest.mark.slow
def test_seed0_regenerates_bundled_k7_jobs2(tmp_path: Path) -> None:
    # 46 s on two idle cores, 112 s with other work on them (load 4.5).
    proc = _generate(tmp_path, 7, 2)
    assert proc.returncode == 0, proc.stderr
    _assert_same_as_bundled(tmp_path, range(3, 8))


@pytest.mark.slow
def test_seed0_regenerates_bundled_k7_jobs1(tmp_path: Path) -> None:
    # 80 s on an idle machine, 89 s with other work on it.
    proc = _generate(tmp_path, 7, 1)
    assert proc.returncode == 0, proc.stderr
    _assert_same_as_bundled(tmp_path, range(3, 8))
