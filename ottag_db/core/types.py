"""Types and constants shared by every sub-package (pure Python, no I/O)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

__all__ = [
    "COMPLETE_COUNTS",
    "COMPLETE_COUNTS_UP_TO_REFLECTION",
    "MP_THRESHOLDS",
    "POLARITIES",
    "QUIET_ZONE",
    "Polarity",
    "ProgressCallback",
    "StageProgress",
]

#: Tone of a tag: ``normal`` (white quiet zone, black data area, white triangles) or
#: ``inverted`` (tones swapped).
Polarity = Literal["normal", "inverted"]
POLARITIES: tuple[Polarity, ...] = ("normal", "inverted")

#: Width of the quiet zone ``export`` prints around a data area, on each side, in data-area
#: units (the printing default; the decoder expects it where it looks past the data area).
QUIET_ZONE = 0.25

#: Progress report of long work: ``callback(done, total)``, both counts of the same unit.
ProgressCallback = Callable[[int, int], None]

#: Progress report of work in named stages: ``callback(stage, done, total)``, the counts of
#: one stage (e.g. ``"realize k=8"``, sets); the CLI shows one bar per stage.
StageProgress = Callable[[str, int, int], None]

#: MP thresholds (grid units) of the paper's Table 7: 0.5, 1.0, …, 9.0.
MP_THRESHOLDS: tuple[float, ...] = tuple(0.5 * i for i in range(1, 19))

#: Number of order types of k points, both chiralities (a complete database holds exactly these).
#: k = 9: 158,817 up to reflection (Aichholzer, Aurenhammer, Krasser 2001), 825 of them achiral,
#: so 2 · 158,817 − 825 = 316,809 (our enumeration, ``ottag-db generate --max-k 9``, agrees).
COMPLETE_COUNTS: dict[int, int] = {3: 1, 4: 2, 5: 3, 6: 20, 7: 242, 8: 6405, 9: 316_809}

#: Number of order types of k points up to reflection (a chiral pair once): the record counts
#: of Aichholzer's files and of the bundled ones, the paper's Table 2.
COMPLETE_COUNTS_UP_TO_REFLECTION: dict[int, int] = {3: 1, 4: 2, 5: 3, 6: 16, 7: 135, 8: 3315, 9: 158_817}
