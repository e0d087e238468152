"""Tags moved by 17 px: a motion's blur measured as one width over all directions, tags whose
largest side's blur passes a twelfth of their side, or whose smeared outline is no quad, read by
model without misreading a look-alike, and the outline of a blurred data area's quiet zone
ranked after the data area for the readings by model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ottag_db.core.lookup import MemoryLookup
from ottag_db.core.types import Polarity
from ottag_db.decode import Detector
from ottag_db.decode.blur import BLURRED_MIN_SIDE, EdgeBlur
from ottag_db.decode.model_budget import around_blurred, rank_for_model
from ottag_db.decode.types import Quad
from tests.decode.test_blur import _frame

_NORMALS = np.eye(2)[[0, 1, 0, 1]]


@pytest.mark.parametrize("angle", [0.0, 20.0, 45.0, 70.0, 90.0])
def test_a_motion_measures_one_width_in_every_direction(angle: float) -> None:
    """A 17 px motion widens a side of normal n by 17 |n·m| / √(2π): the largest side measures
    up to 6.8 px (beyond a twelfth of an 80 px data area along a side's normal, 4.8 px along the
    diagonal), its width over directions is 17 / √(4π) = 4.8 px in every direction; a defocus's
    width is its σ."""
    length, theta = 17.0, math.radians(angle)
    a, b = (length * abs(f) / math.sqrt(2 * math.pi) for f in (math.cos(theta), math.sin(theta)))
    moved = EdgeBlur((a, b, a, b), _NORMALS)
    assert moved.width == pytest.approx(length / math.sqrt(4 * math.pi))
    assert moved.width <= 80.0 / BLURRED_MIN_SIDE
    assert EdgeBlur((3.0, 3.0, 3.0, 3.0), _NORMALS).width == pytest.approx(3.0)
    assert EdgeBlur((3.0, 2.0, 2.5, math.nan), _NORMALS).width == pytest.approx(math.sqrt((9.0 + 4.0) / 2))
    assert EdgeBlur((3.0, math.nan, 2.5, math.nan), _NORMALS).width == 0.0


# Seeds of tests.decode.test_blur._frame (tags 98 px frontal, moved by 17 px) none of which read
# before: 209, 213 and 235 measure their largest side's blur beyond a twelfth of their side
# (8.1-8.2 px on 92-95 px), 240 reads only with both the floor of its coarse match reached at
# half a ranking cell of blur and the nominal correlation of 0.7 (either one as before: not
# read), and 262 is outlined by the lines of its smeared sides (an inferred quad).
_UNREAD_BEFORE = (209, 213, 235, 240, 262)


def test_long_motions_read_and_no_look_alike_reads_in_their_place(printed) -> None:
    """Each of those tags reads, and only as itself; with the tags drawn taken out of the
    lookup, no other tag is read in their place."""
    lookup, tags = printed
    drawn = {t.lambda_text for t in tags}
    without = MemoryLookup(e for e in lookup if e.lambda_text not in drawn)  # type: ignore[attr-defined]
    det, det_without = Detector(lookup), Detector(without)
    read = []
    for seed in _UNREAD_BEFORE:
        tag, image, _ = _frame(tags, seed, "normal", motion=17)
        found = det.detect(image)
        assert all(d.lambda_text == tag.lambda_text for d in found)
        if any(d.lambda_text == tag.lambda_text for d in found):
            read.append(seed)
        assert det_without.detect(image) == []
    assert read == list(_UNREAD_BEFORE)


def _square(centre: tuple[float, float], side: float, polarity: Polarity = "normal") -> Quad:
    half = side / 2
    corners = np.array(centre) + half * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    return Quad(polarity, corners, side * side)


def test_a_blurred_data_areas_quiet_zone_outline_ranks_after_it() -> None:
    """A tag 82 px wide moved by 17 px: its data area (blurred, coarse match 0.655) and the
    outlines of its quiet zone's outer edge (133 and 138 px, both polarities; 0.755 and 0.666)
    want the pass's two readings by model; the data area gets one, the better outline the other.
    A triangle's piece inside it (20 px) and a quad elsewhere rank by their match as before."""
    quads = [
        _square((300, 200), 82.0),
        _square((301, 201), 133.0, "inverted"),
        _square((302, 199), 138.0),
        _square((310, 190), 20.0),
        _square((500, 400), 60.0),
    ]
    blurred = [True, True, True, True, False]
    last = around_blurred(quads, blurred)
    assert last == [False, True, True, False, False]
    scores = [0.655, 0.755, 0.666, 0.3, 0.2]
    assert rank_for_model(scores[:3], 2) == ([1, 2], [0])  # the outlines take the readings
    assert rank_for_model(scores[:3], 2, last[:3]) == ([0, 1], [2])
    assert rank_for_model(scores, 3, last) == ([0, 3, 4], [1, 2])
