"""Fixtures shared by the decoder's tests."""

from __future__ import annotations

import pytest

from tests.support.tagsynth import scene_data


@pytest.fixture(scope="module")
def bundled(bundled_db_path):
    """Lookup (k = 5 … 8) and drawable tags of the bundled data, read as the project reads them."""
    return scene_data(bundled_db_path)
