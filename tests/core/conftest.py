"""Fixtures of the core tests: point sets of every source that is available."""

from __future__ import annotations

import os

import numpy as np
import pytest

#: The bundled data always; Aichholzer's reference files as an extra layer when configured
#: (not collected otherwise, so the suite does not skip them).
SOURCES = ["bundled"] + (["reference"] if os.environ.get("OTTAG_AICHHOLZER_DIR") else [])


@pytest.fixture(params=SOURCES)
def point_sets(request: pytest.FixtureRequest) -> dict[int, np.ndarray]:
    """Point sets per k (3 … 8) of one source, ``(records, k, 2)`` int64, one per reflection pair.

    Both sources hold the same order types (the same IDs), with other coordinates.
    """
    sets: dict[int, np.ndarray] = request.getfixturevalue(f"{request.param}_sets")
    return sets
