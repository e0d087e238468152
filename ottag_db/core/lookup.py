"""The lookup interface between the decoder and a tag store (database, dictionary, memory)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = ["LookupEntry", "MemoryLookup", "TagLookup"]


@dataclass(frozen=True)
class LookupEntry:
    """One order type a decoder may report.

    - ``lambda_text``: canonical ID ``k:digits``; ``k`` its number of points;
    - ``order_type_id``: database id (or any stable integer of the store);
    - ``unique_min``: one minimal canonical ordering (point matching is unambiguous);
    - ``realizations``: stored point sets of this order type, each ``(k, 2)`` float64 in
      file (grid) coordinates, rows in *canonical label order* (row ``l`` is the point with
      canonical label ``l``), screen convention (x right, y down);
    - ``tag``: number of the tag in the loaded dictionary, or None;
    - ``extra``: store-specific values (a dictionary's ``"tags"``: polarity → number);
    - ``layouts``: ``layouts[r]`` the triangles printed for ``realizations[r]`` as triples of
      canonical labels (an empty tuple when the store does not know them; the whole field
      empty when it knows none). Soft decoding accepts a corrected reading only when its
      triangles are these (:mod:`ottag_db.decode.soft`);
    - ``placements``: ``placements[r]`` the ``(2, 3)`` affine map (float64) that printed
      ``realizations[r]`` into the data area (grid → data-area units [0, 1]², x right, y
      down; :func:`ottag_db.core.placement.tag_placements`), None when the store does not
      know it; the whole field empty when it knows none (a portable dictionary file).
      Verification then checks that the printed points land where the data-area corners
      put them (:mod:`ottag_db.decode.placement_check`).
    """

    lambda_text: str
    k: int
    order_type_id: int
    unique_min: bool
    realizations: tuple[NDArray[np.float64], ...]
    tag: int | None = None
    extra: Mapping[str, object] = field(default_factory=dict)
    layouts: tuple[tuple[tuple[int, int, int], ...], ...] = ()
    placements: tuple[NDArray[np.float64] | None, ...] = ()


@runtime_checkable
class TagLookup(Protocol):
    """What the decoder needs from a tag store: find an order type by canonical ID."""

    def get(self, lambda_text: str) -> LookupEntry | None:
        """Find an order type by canonical ID.

        Parameters
        ----------
        lambda_text : str
            Canonical ID ``k:digits``.

        Returns
        -------
        LookupEntry or None
            The entry, or None when the store does not hold the ID.
        """
        ...

    def __len__(self) -> int: ...

    @property
    def ks(self) -> frozenset[int]:
        """Point counts present in the store (the decoder only reads these)."""
        ...


class MemoryLookup:
    """A :class:`TagLookup` held in a dict; built once, read per frame without I/O.

    Parameters
    ----------
    entries : iterable of LookupEntry
        The order types (a later entry with the same ID replaces an earlier one).
    """

    def __init__(self, entries: Iterable[LookupEntry]):
        self._entries: dict[str, LookupEntry] = {}
        for e in entries:
            self._entries[e.lambda_text] = e
        self._ks = frozenset(e.k for e in self._entries.values())

    def get(self, lambda_text: str) -> LookupEntry | None:
        """Find an order type by canonical ID.

        Parameters
        ----------
        lambda_text : str
            Canonical ID ``k:digits``.

        Returns
        -------
        LookupEntry or None
            The entry, or None when the lookup does not hold the ID.
        """
        return self._entries.get(lambda_text)

    def __len__(self) -> int:
        return len(self._entries)

    def __iter__(self) -> Iterator[LookupEntry]:
        return iter(self._entries.values())

    @property
    def ks(self) -> frozenset[int]:
        """Point counts present in the store."""
        return self._ks
