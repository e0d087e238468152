"""Option texts as a user types them (lengths with units, page names) turned into sheet settings.

The parsers are :func:`ottag_db.printing.sheet.parse_length` and
:func:`ottag_db.printing.sheet.parse_page`.
"""

from __future__ import annotations

from ottag_db.printing.sheet import SheetOptions, parse_length, parse_page

__all__ = ["sheet_options"]


def sheet_options(
    *,
    tag_size: str,
    quiet_zone: str | None,
    page: str,
    margin: str,
    spacing: str,
    labels: bool,
    cut_marks: bool,
    pack: bool = True,
) -> SheetOptions:
    """Sheet settings of ``ottag-db export`` from its option texts.

    Parameters
    ----------
    tag_size : str
        Side of the black data area with a unit (``"50mm"``, ``"5cm"``, ``"2in"``, ``"72pt"``).
    quiet_zone : str or None
        White border around the data area with a unit; None for 0.25 × tag size.
    page : str
        ``"A4"``, ``"Letter"``, ``"A4-landscape"`` … or ``"WxH"`` with a unit (``"210x297mm"``).
    margin : str
        Page margin with a unit.
    spacing : str
        Extra paper between neighbouring tags beyond their quiet zones, with a unit (may be 0).
    labels : bool
        A label under each tag.
    cut_marks : bool
        Corner marks for cutting (each tag keeps its whole quiet zone).
    pack : bool
        Neighbours of one polarity share their quiet zones (see
        :mod:`ottag_db.printing.sheet_layout`).

    Returns
    -------
    SheetOptions
        The settings with every length in mm.

    Raises
    ------
    UsageError
        For the first text (in the order of the parameters) without a known unit or not > 0
        (spacing: not ≥ 0).
    """
    return SheetOptions(
        tag_size_mm=parse_length(tag_size),
        quiet_zone_mm=None if quiet_zone is None else parse_length(quiet_zone),
        page=parse_page(page),
        margin_mm=parse_length(margin),
        spacing_mm=parse_length(spacing, allow_zero=True),
        labels=labels,
        cut_marks=cut_marks,
        pack=pack,
    )
