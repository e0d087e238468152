"""Where tags go on a sheet page: a packed grid, label bands, header and footer (no drawing).

Packing rules (lengths in mm, page coordinates from the lower-left corner, PDF y up):

- A tag's quiet zone only has to be free of the other tone's ink. Neighbours of one polarity
  may therefore *share* their quiet zones: two normal tags (white quiet zones) or two
  inverted tags (black quiet zones) can stand one quiet zone apart, data area to data area.
  A normal tag next to an inverted one cannot (white and black zones would overlap), and tags
  meant to be cut apart (cut marks) keep their whole quiet zone each: then the outer squares
  are ``spacing`` apart (at least ``2 × cut-mark length + 1`` with cut marks).
- A sheet packs when it holds tags of one polarity only, ``pack`` is on and cut marks are off;
  the decision is made per sheet, so every page has the same grid (deterministic).
- Labels are ink, so they never enter any quiet zone: each label sits in a band under its
  tag's outer square, between rows, on one line when every label of the sheet fits the
  column width at ≥ 5 pt, else on two. With labels, rows do not share quiet zones.
- Header (title, selection, sizes and print note) and footer (100 mm ruler with the printer
  note beside it) are kept low so that more rows fit.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ottag_db.errors import ExportError, UsageError
from ottag_db.printing.pdf import MM_TO_PT

if TYPE_CHECKING:
    from ottag_db.printing.sheet import SheetOptions

__all__ = ["RULER_LENGTH_MM", "SheetLayout", "plan_sheet"]

#: Length of the printer-check ruler on every page, mm.
RULER_LENGTH_MM = 100.0

HEADER_MM = 10.5  # title, selection, sizes/print note: three lines
FOOTER_MM = 8.0  # ruler with the printer note beside it
FOOTER_NARROW_MM = 12.0  # note under the ruler, on pages too narrow for both side by side
NOTE_BESIDE_MM = 8.0 + 60.0  # room right of the ruler the note needs ("cm" + text)
MIN_LABEL_PT = 3.5
ONE_LINE_MIN_PT = 5.0  # a one-line label is never smaller than this
LEADING = 1.2
CUT_MARK_MM = 2.0
LABEL_PAD_MM = 0.4  # paper under a label before the next row's quiet zone
MIN_DATA_GAP_MM = 1.0  # data areas never closer than this (no quiet zone and no spacing)


@dataclass(frozen=True)
class SheetLayout:
    """The grid of a sheet page (every page of a sheet has the same one); lengths in mm.

    - ``page``: ``(width, height)``;
    - ``columns``, ``rows``: tags per row and per column; slots fill row by row from the top left;
    - ``x0``: left edge of the first column's outer square (quiet zone included);
    - ``top``: top edge of the first row's outer square, from the page's bottom edge;
    - ``pitch_x``, ``pitch_y``: distance between neighbouring tags' outer squares;
    - ``total``: side of a tag's outer square (data area + 2 quiet zones); ``quiet``: quiet zone;
    - ``packed``: neighbours share their quiet zones (one polarity, no cut marks);
    - ``label_lines``: 0 (no labels), 1 or 2; ``label_gap``: paper between the outer square
      and the label; ``label_width``: room for a label (never over a neighbour's label);
    - ``label_band``: height under a tag taken by its label (0 without labels);
    - ``mark_len``: cut-mark length (0: none); ``footer_mm``: footer height above the margin.
    """

    page: tuple[float, float]
    columns: int
    rows: int
    x0: float
    top: float
    pitch_x: float
    pitch_y: float
    total: float
    quiet: float
    packed: bool
    label_lines: int
    label_gap: float
    label_width: float
    label_band: float
    mark_len: float
    footer_mm: float

    @property
    def per_page(self) -> int:
        """Tags on a full page."""
        return self.columns * self.rows

    def tag_origin(self, slot: int) -> tuple[float, float]:
        """Lower-left corner of the outer square of the ``slot``-th tag of a page.

        Parameters
        ----------
        slot : int
            0 … ``per_page − 1``, row by row from the top left.

        Returns
        -------
        tuple of float
            ``(x, y)`` in mm from the page's lower-left corner (PDF y up).
        """
        row, col = divmod(slot, self.columns)
        return self.x0 + col * self.pitch_x, self.top - row * self.pitch_y - self.total


def _count(avail: float, pitch: float, extent: float) -> int:
    """How many cells of ``extent`` repeated every ``pitch`` fit in ``avail``."""
    if avail + 1e-9 < extent:
        return 0
    return math.floor((avail - extent) / pitch + 1e-9) + 1


def _one_line_fits(labels: Iterable[tuple[str, str]], width_pt: float) -> bool:
    from reportlab.pdfbase.pdfmetrics import stringWidth

    size = ONE_LINE_MIN_PT
    return all(
        stringWidth(first, "Helvetica-Bold", size) + stringWidth("  " + second, "Helvetica", size) <= width_pt
        for first, second in labels
    )


def _check_sizes(options: SheetOptions) -> float:
    for name in ("tag_size_mm", "margin_mm", "spacing_mm", "label_font_pt"):
        value = float(getattr(options, name))
        if not math.isfinite(value) or value < 0 or (name in ("tag_size_mm", "label_font_pt") and value == 0):
            raise UsageError(f"{name.replace('_mm', '').replace('_', ' ')} must be positive, got {value}")
    quiet = options.quiet_mm()
    if not math.isfinite(quiet) or quiet < 0:
        raise UsageError(f"quiet zone must be zero or positive, got {quiet}")
    return quiet


def plan_sheet(
    options: SheetOptions,
    polarities: Iterable[str] | None = None,
    labels: Sequence[tuple[str, str]] | None = None,
) -> SheetLayout:
    """The grid that fits the most tags on a page of ``options``.

    Parameters
    ----------
    options : SheetOptions
        Sheet settings.
    polarities : iterable of str, optional
        Polarities of the sheet's tags; one polarity lets neighbours share quiet zones
        (unless ``options.pack`` is off or cut marks are on). None: unknown, no sharing.
    labels : sequence of (str, str), optional
        The sheet's label texts (bold ID part, detail part); one line when all fit the column
        at ≥ 5 pt. None: two lines (the grid then holds any labels).

    Returns
    -------
    SheetLayout
        Grid, pitches, label band and header/footer room.

    Raises
    ------
    ExportError
        Not one tag (or the ruler) fits the page.
    UsageError
        Bad sizes.
    """
    quiet = _check_sizes(options)
    pw, ph = options.page_size_mm()
    m = options.margin_mm
    size = options.tag_size_mm
    sp = options.spacing_mm
    total = size + 2 * quiet
    avail_w = pw - 2 * m
    if avail_w < RULER_LENGTH_MM:
        raise ExportError(
            f"page {pw:g} × {ph:g} mm with {m:g} mm margins is {avail_w:g} mm wide inside the margins; "
            f"the {RULER_LENGTH_MM:g} mm printer-check ruler needs at least {RULER_LENGTH_MM:g} mm "
            "(use a larger page or smaller margins)"
        )
    mark = CUT_MARK_MM if options.cut_marks else 0.0
    gap = max(sp, 2 * mark + 1.0) if options.cut_marks else sp  # between outer squares, not shared
    pols = None if polarities is None else set(polarities)
    packed = bool(options.pack and not options.cut_marks and pols is not None and len(pols) == 1)
    pitch_shared = max(size + quiet + sp, size + MIN_DATA_GAP_MM)
    pitch_x = pitch_shared if packed else max(total + gap, size + MIN_DATA_GAP_MM)
    label_width = max(min(total, pitch_x - 1.0), 0.5 * total)
    lines = 0
    if options.labels:
        lines = 1 if labels is not None and _one_line_fits(labels, label_width * MM_TO_PT) else 2
    label_gap = mark + 0.5 if options.cut_marks else 0.8
    line_mm = options.label_font_pt * LEADING / MM_TO_PT
    band = label_gap + lines * line_mm + LABEL_PAD_MM + mark if lines else 0.0
    if lines:
        pitch_y, extent_y = total + max(gap, band), total + band
    else:
        pitch_y, extent_y = (pitch_shared if packed else pitch_x), total + mark
    footer = FOOTER_MM if avail_w >= RULER_LENGTH_MM + NOTE_BESIDE_MM else FOOTER_NARROW_MM
    top_pad = mark + 0.5 if mark else 0.0
    avail_h = ph - 2 * m - HEADER_MM - footer - top_pad
    cols = _count(avail_w, pitch_x, total)  # outermost cut marks may reach into the margin
    rows = _count(avail_h, pitch_y, extent_y)
    if cols < 1 or rows < 1:
        raise ExportError(
            f"a tag of {total:g} mm ({size:g} mm data area + 2 × {quiet:g} mm quiet zone"
            + (f", plus {band:.1f} mm label" if lines else "")
            + f") does not fit the {max(avail_w, 0):g} × {max(avail_h, 0):g} mm tag area of the "
            f"{pw:g} × {ph:g} mm page ({m:g} mm margins, header and ruler); use a smaller tag size "
            "or quiet zone, smaller margins, or a larger page"
        )
    grid_w = (cols - 1) * pitch_x + total
    return SheetLayout(
        page=(pw, ph),
        columns=cols,
        rows=rows,
        x0=m + (avail_w - grid_w) / 2.0,
        top=ph - m - HEADER_MM - top_pad,
        pitch_x=pitch_x,
        pitch_y=pitch_y,
        total=total,
        quiet=quiet,
        packed=packed,
        label_lines=lines,
        label_gap=label_gap,
        label_width=label_width,
        label_band=band,
        mark_len=mark,
        footer_mm=footer,
    )
