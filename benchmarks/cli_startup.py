"""Wall time of short ``ottag-db`` commands against ``python -c "import numpy"``, measured in one run.

Each command runs in a fresh process (start-up included, as a user sees it). The rounds are
interleaved — numpy, --version, stats, id, numpy, … — so that load on the machine touches all
of them alike; the best of the rounds is reported with its ratio to the numpy baseline.
``stats`` and ``id`` read a database built first in a temporary folder with
``ottag-db import --quiet`` (the bundled data). Target: ``--version`` at most 1.5 × numpy.

The cold start of ``ottag-db decode one.png`` (an 8-point tag drawn by ``ottag-db render``) is
measured too (target: at most 2.0 s on every run after the first, issue 37), with what the
decoder's compiled kernels add to it (``ottag_native``, Cython, compiled by ``pip install .``:
importing them beside numpy), and what a decoder compiled with Numba would add instead:
``import numba`` and the first call of a kernel compiled with ``@njit(cache=True)`` whose cache a
first run (timed on its own: that run compiles) has already written. The decoder does not use
Numba; those rows only measure what it would cost.

Usage: python benchmarks/cli_startup.py [--rounds N]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: The point set of the paper's Fig. 8 (an order type of 5 points in the bundled data).
FIG8_POINTS = "0,0 69,255 149,116 138,72 255,69"
TARGET_VERSION_RATIO = 1.5
#: The cold start of ``ottag-db decode one.png`` on every run after the first (s, issue 37).
TARGET_DECODE_START_S = 2.0
#: The tag decoded: an 8-point order type of the bundled data (as users print).
DECODED_ID = "8:0654321000321465130325432430343235430321421230545023410661345200"
#: A module with one small kernel compiled with Numba's on-disk cache (the kind of loop a
#: compiled decoder stage would be), and the call that loads it.
NUMBA_KERNEL = """
import numpy as np
from numba import njit


@njit(cache=True)
def orientations(points):
    n = points.shape[0]
    out = np.empty((n, n, n), dtype=np.int8)
    for i in range(n):
        for j in range(n):
            for k in range(n):
                d = (points[j, 0] - points[i, 0]) * (points[k, 1] - points[i, 1]) - (
                    points[j, 1] - points[i, 1]
                ) * (points[k, 0] - points[i, 0])
                out[i, j, k] = (d > 0) - (d < 0)
    return out
"""


def _ottag_db() -> list[str]:
    """The installed console script next to this interpreter, else ``python -m ottag_db``."""
    script = Path(sys.executable).with_name("ottag-db")
    if script.exists():
        return [str(script)]
    found = shutil.which("ottag-db")
    return [found] if found else [sys.executable, "-m", "ottag_db"]


def _run(cmd: list[str]) -> float:
    """Seconds of wall time of one run of ``cmd``; a failing command stops the benchmark."""
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    elapsed = time.perf_counter() - t
    if proc.returncode != 0:
        sys.exit(f"error: {' '.join(cmd)} exited with {proc.returncode}:\n{proc.stderr.strip()}")
    return elapsed


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7, help="interleaved rounds; the best is reported [7]")
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error(f"--rounds must be at least 1, got {args.rounds}")
    tool = _ottag_db()
    with tempfile.TemporaryDirectory() as tmp:
        db = str(Path(tmp) / "db.sqlite")
        t = time.perf_counter()
        _run([*tool, "import", "--db", db, "--quiet"])
        print(f"database built with `ottag-db import --quiet` in {time.perf_counter() - t:.1f} s")
        image = str(Path(tmp) / "one.png")
        _run([*tool, "render", "--db", db, "--quiet", "--px", "200", DECODED_ID, image])
        decoded = subprocess.run([*tool, "decode", "--db", db, "--json", image], capture_output=True, text=True).stdout
        if DECODED_ID not in decoded:
            sys.exit(f"error: ottag-db decode did not read {DECODED_ID} from the rendered tag")
        Path(tmp, "kernel.py").write_text(NUMBA_KERNEL)
        load_kernel = "; ".join(
            (
                "import sys",
                f"sys.path.insert(0, {tmp!r})",
                "import numpy, kernel",
                "kernel.orientations(numpy.ones((8, 2)))",
            )
        )
        commands = {
            'python -c "import numpy"': [sys.executable, "-c", "import numpy"],
            "ottag-db --version": [*tool, "--version"],
            "ottag-db stats": [*tool, "stats", "--db", db],
            f'ottag-db id "{FIG8_POINTS}"': [*tool, "id", "--db", db, FIG8_POINTS],
            "ottag-db decode one.png": [*tool, "decode", "--db", db, "--quiet", image],
            "numpy and the compiled kernels (ottag_native)": [
                sys.executable,
                "-c",
                "import numpy, ottag_native.blur, ottag_native.lines, ottag_native.triangles",
            ],
            'python -c "import numba"': [sys.executable, "-c", "import numba"],
            "numba: one cached kernel, first call": [sys.executable, "-c", load_kernel],
        }
        compiling = _run(commands["numba: one cached kernel, first call"])  # writes the kernel's cache
        for cmd in commands.values():  # warm the file cache; not timed
            _run(cmd)
        times: dict[str, list[float]] = {name: [] for name in commands}
        for _ in range(args.rounds):
            for name, cmd in commands.items():
                times[name].append(_run(cmd))
    baseline = min(times['python -c "import numpy"'])
    print(f"best of {args.rounds} interleaved rounds (median in brackets), ratio to the numpy baseline:")
    for name, values in times.items():
        best, median = min(values), statistics.median(values)
        print(f"  {name:<52} {best * 1000:7.0f} ms ({median * 1000:5.0f} ms)  {best / baseline:5.2f}×")
    ratio = min(times["ottag-db --version"]) / baseline
    verdict = "met" if ratio <= TARGET_VERSION_RATIO else "NOT met"
    print(f"target --version <= {TARGET_VERSION_RATIO}× numpy: {verdict} ({ratio:.2f}×)")
    decode_start = min(times["ottag-db decode one.png"])
    kernels = min(times["numpy and the compiled kernels (ottag_native)"]) - baseline
    verdict = "met" if decode_start <= TARGET_DECODE_START_S else "NOT met"
    print(
        f"target decode's cold start <= {TARGET_DECODE_START_S} s: {verdict} ({decode_start:.2f} s,"
        f" of which the compiled kernels' import {kernels * 1000:.0f} ms beyond numpy's)"
    )
    # A compiled decoder imports numpy anyway: what Numba adds is its own import and its cache.
    added = min(times["numba: one cached kernel, first call"]) - baseline
    print(
        f"a decoder compiled with Numba: decode's cold start {decode_start:.2f} s would grow by at least"
        f" {added:.2f} s (import numba and load one cached kernel),"
        f" and the first run after an install, which compiles, by {compiling - baseline:.2f} s for that one kernel"
    )


if __name__ == "__main__":
    main()
