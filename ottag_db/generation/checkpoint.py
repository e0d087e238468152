"""Finished realization batches kept on disk, so an interrupted ``generate`` resumes.

One small ``.npz`` per finished batch in a work folder, named by k, seed, batch index and a
hash of the batch's input (points, IDs, seed, effort): a rerun finds the batches it already
did and only computes the others. A file whose name or content does not match the batch is
ignored (and overwritten when the batch is recomputed); files are written atomically.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["BatchStore", "StoredBatch", "batch_digest"]

#: Names of the files a :class:`BatchStore` writes (and :meth:`BatchStore.clear` removes).
_NAME = re.compile(r"^k\d{2}-seed-?\d+-b\d{5}-[0-9a-f]{16}\.npz$")


@dataclass(frozen=True)
class StoredBatch:
    """One finished batch: ``texts`` (canonical IDs), ``points`` ``(B, k, 2)`` int64 in [0, 255]²,
    ``mp`` and ``continuous_mp`` ``(B,)`` float64 (grid units)."""

    texts: tuple[str, ...]
    points: NDArray[np.int64]
    mp: NDArray[np.float64]
    continuous_mp: NDArray[np.float64]


def batch_digest(points: NDArray[np.float64], texts: list[str], seed: int, effort: object) -> str:
    """Hash of everything a batch's result depends on.

    Parameters
    ----------
    points : ndarray of float64, shape (B, k, 2)
        The input realizations.
    texts : list of str
        Their canonical IDs.
    seed : int
        Run seed.
    effort : object
        The search effort; its ``repr`` is hashed (a frozen dataclass).

    Returns
    -------
    str
        16 hex digits (a prefix of SHA-256).
    """
    h = hashlib.sha256()
    h.update(f"{seed}|{effort!r}|{points.shape}|".encode())
    h.update("\n".join(texts).encode("ascii"))
    h.update(np.ascontiguousarray(points, dtype="<f8").tobytes())
    return h.hexdigest()[:16]


class BatchStore:
    """The work folder of one run (created on the first write)."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)

    def path(self, k: int, seed: int, index: int, digest: str) -> Path:
        """File of batch ``index`` of the ``k``-point sets of a run with ``seed``.

        Parameters
        ----------
        k : int
            Points per set.
        seed : int
            Run seed.
        index : int
            Batch index within the k.
        digest : str
            :func:`batch_digest` of the batch.

        Returns
        -------
        Path
            ``kNN-seedS-bIIIII-DIGEST.npz`` in the folder.
        """
        return self.folder / f"k{k:02d}-seed{seed}-b{index:05d}-{digest}.npz"

    def load(self, path: Path, texts: list[str]) -> StoredBatch | None:
        """The stored batch at ``path`` if it is complete and holds ``texts``; None otherwise.

        Parameters
        ----------
        path : Path
            From :meth:`path`.
        texts : list of str
            The IDs the batch must hold, in order.

        Returns
        -------
        StoredBatch or None
            The stored results, or None when missing or not matching.
        """
        try:
            with np.load(path, allow_pickle=False) as data:
                stored = StoredBatch(
                    texts=tuple(str(t) for t in data["texts"]),
                    points=np.asarray(data["points"], dtype=np.int64),
                    mp=np.asarray(data["mp"], dtype=np.float64),
                    continuous_mp=np.asarray(data["continuous_mp"], dtype=np.float64),
                )
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
            return None
        n = len(texts)
        if (
            list(stored.texts) != texts
            or stored.points.shape[0] != n
            or stored.mp.shape != (n,)
            or stored.continuous_mp.shape != (n,)
        ):
            return None
        return stored

    def save(self, path: Path, batch: StoredBatch) -> None:
        """Write ``batch`` to ``path`` atomically (a temporary file, then a rename).

        Parameters
        ----------
        path : Path
            From :meth:`path`.
        batch : StoredBatch
            The finished results.
        """
        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
        with open(tmp, "wb") as fh:
            np.savez(
                fh,
                texts=np.array(batch.texts, dtype=np.str_),
                points=batch.points,
                mp=batch.mp,
                continuous_mp=batch.continuous_mp,
            )
        os.replace(tmp, path)

    def clear(self) -> None:
        """Delete this store's batch files (and leftover temporary files), then the folder if empty."""
        if not self.folder.is_dir():
            return
        for entry in self.folder.iterdir():
            name = entry.name
            if _NAME.match(name) or (name.endswith(".tmp") and _NAME.match(name.split(".npz")[0] + ".npz")):
                entry.unlink(missing_ok=True)
        with contextlib.suppress(OSError):  # not empty: other files are the user's
            self.folder.rmdir()
