"""Where the tests' point sets come from: the bundled data always, Aichholzer's files when configured."""

from __future__ import annotations

import os
from pathlib import Path


def aichholzer_dir() -> Path | None:
    """The folder in ``$OTTAG_AICHHOLZER_DIR`` (Aichholzer's ``otypes03.b08`` …), or None when unset."""
    value = os.environ.get("OTTAG_AICHHOLZER_DIR")
    return Path(value) if value else None


#: Point-set sources a parametrized test runs on: the bundled data always, the reference files
#: as the extra layer when configured (not collected otherwise, so the suite does not skip them).
POINT_SET_SOURCES = ["bundled"] + (["reference"] if aichholzer_dir() is not None else [])
