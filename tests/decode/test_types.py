"""Decoder data types: reasons, settings validation, stage values."""

from __future__ import annotations

from typing import get_args

import numpy as np
import pytest

from ottag_db.decode import REJECTION_REASONS, STAGES, DetectorParams, RejectReason
from ottag_db.decode.types import Decomposition, Quad, Rejection
from ottag_db.errors import UsageError


def test_reject_reasons_are_the_documented_keys() -> None:
    assert tuple(REJECTION_REASONS) == get_args(RejectReason)
    assert "polarity_not_in_dictionary" in REJECTION_REASONS
    assert STAGES[0] == "image" and len(set(STAGES)) == len(STAGES)


def test_params_validation() -> None:
    assert DetectorParams().polarities == ("normal", "inverted")
    assert DetectorParams(polarities="inverted").polarities == ("inverted",)  # type: ignore[arg-type]
    assert DetectorParams(polarities=["normal"]).polarities == ("normal",)  # type: ignore[arg-type]
    for bad in (
        {"adaptive_block": 4},
        {"adaptive_block": 1},
        {"polarities": ("sideways",)},
        {"use_otsu": False, "use_adaptive": False},
        {"min_margin_px": -1.0},
        {"max_reproj_px": -0.5},
        {"model_misfit_lead": -0.05},
    ):
        with pytest.raises(UsageError):
            DetectorParams(**bad)  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        DetectorParams(no_such_option=1)  # type: ignore[call-arg]


def test_rejection_at_quad_and_decomposition_count() -> None:
    corners = np.array([[0, 0], [10, 0], [10, 10], [0, 10.0]])
    quad = Quad("inverted", corners, 100.0)
    rej = Rejection("unknown_id", "detail", "3:010001100").at(quad)
    assert (rej.reason, rej.polarity, rej.lambda_text, rej.detail) == (
        "unknown_id",
        "inverted",
        "3:010001100",
        "detail",
    )
    assert np.array_equal(rej.corners, corners) and rej.corners is not corners
    chain = np.zeros((2, 2))
    assert Decomposition((chain,) * 6).count == 2 and Decomposition(()).count == 0
