"""Tests of ottag_db.app.options: sheet settings from option texts."""

from __future__ import annotations

import pytest

from ottag_db.app.options import parse_length, sheet_options
from ottag_db.errors import UsageError
from ottag_db.printing.sheet import SheetOptions

DEFAULTS = {
    "tag_size": "50mm",
    "quiet_zone": None,
    "page": "A4",
    "margin": "10mm",
    "spacing": "5mm",
    "labels": True,
    "cut_marks": False,
}


def test_defaults_of_export() -> None:
    opts = sheet_options(**DEFAULTS)  # type: ignore[arg-type]
    assert opts == SheetOptions(
        tag_size_mm=50.0,
        quiet_zone_mm=None,
        page=(210.0, 297.0),
        margin_mm=10.0,
        spacing_mm=5.0,
        labels=True,
        cut_marks=False,
    )


def test_units_and_flags() -> None:
    opts = sheet_options(
        tag_size="3cm", quiet_zone="0.5in", page="Letter", margin="1cm", spacing="72pt", labels=False, cut_marks=True
    )
    assert opts.tag_size_mm == pytest.approx(30.0) and opts.quiet_zone_mm == pytest.approx(12.7)
    assert opts.spacing_mm == pytest.approx(25.4) and opts.margin_mm == pytest.approx(10.0)
    assert opts.page == pytest.approx((215.9, 279.4)) and not opts.labels and opts.cut_marks
    assert parse_length("2in") == pytest.approx(50.8)


def test_first_bad_text_is_reported() -> None:
    with pytest.raises(UsageError, match="'5xx'"):
        sheet_options(**{**DEFAULTS, "tag_size": "5xx", "margin": "1yy"})  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="'1yy'"):
        sheet_options(**{**DEFAULTS, "margin": "1yy"})  # type: ignore[arg-type]
    with pytest.raises(UsageError):
        sheet_options(**{**DEFAULTS, "page": "B9"})  # type: ignore[arg-type]
