"""Per-stage and per-pass wall time of one decode call (as AprilTag's time profile)."""

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
        self._passes: list[tuple[str, float]] = []  # (candidate pass, when it started)
        self._passes_end: float | None = None

    def lap(self, stage: StageName) -> None:
        """Charge the time since the previous lap to ``stage``."""
        now = time.perf_counter()
        self._spent[stage] += now - self._last
        self._last = now

    def timings(self) -> tuple[tuple[StageName, float], ...]:
        """``(stage, seconds)`` for every stage of :data:`~ottag_db.decode.types.STAGES`, in order."""
        return tuple(self._spent.items())

    def start_pass(self, name: str) -> None:
        """Mark the start of candidate pass ``name``; the previous pass ends here."""
        self._passes.append((name, time.perf_counter()))

    def end_passes(self) -> None:
        """Mark the end of the frame's last candidate pass."""
        self._passes_end = time.perf_counter()

    def pass_timings(self) -> tuple[tuple[str, float], ...]:
        """``(pass, seconds)`` for every candidate pass that ran, in order: from its start to the
        next pass's (the last one's to :meth:`end_passes`), its readings and reading by model
        included."""
        if not self._passes:
            return ()
        ends = [t for _, t in self._passes[1:]] + [self._passes_end if self._passes_end is not None else self._last]
        return tuple((name, max(end - start, 0.0)) for (name, start), end in zip(self._passes, ends, strict=True))
