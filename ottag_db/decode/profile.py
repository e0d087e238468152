"""Per-stage wall time of one decode call (as AprilTag's time profile)."""

from __future__ import annotations

import time

from ottag_db.decode.types import STAGES, StageName

__all__ = ["StageClock"]


class StageClock:
    """Accumulates wall time per stage for one :meth:`~ottag_db.decode.Detector.detect` call.

    Each :meth:`lap` charges the time since the previous lap (or since the clock started) to
    the named stage, like AprilTag's ``timeprofile_stamp``. One clock belongs to one call:
    the detector creates it per frame, so concurrent calls never share one.
    """

    def __init__(self) -> None:
        self._last = time.perf_counter()
        self._spent: dict[StageName, float] = dict.fromkeys(STAGES, 0.0)

    def lap(self, stage: StageName) -> None:
        """Charge the time since the previous lap to ``stage``."""
        now = time.perf_counter()
        self._spent[stage] += now - self._last
        self._last = now

    def timings(self) -> tuple[tuple[StageName, float], ...]:
        """``(stage, seconds)`` for every stage of :data:`~ottag_db.decode.types.STAGES`, in order."""
        return tuple(self._spent.items())
