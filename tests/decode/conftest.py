"""Fixtures shared by the decoder's tests."""

from __future__ import annotations

import pytest

from tests.support.grazing import printed_tags
from tests.support.tagsynth import scene_data


@pytest.fixture(scope="module")
def bundled(bundled_db_path):
    """Lookup (k = 5 … 8) and drawable tags of the bundled data, read as the project reads them."""
    return scene_data(bundled_db_path)


@pytest.fixture(scope="module")
def printed(bundled_db_path):
    """Lookup (k = 5 … 8) and the 24 k = 8 tags of largest MP as ``export`` draws them."""
    return printed_tags(bundled_db_path)
