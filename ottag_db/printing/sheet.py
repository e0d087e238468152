"""Printable PDF tag sheets: tags in a grid with labels, cut marks, print notes and a test ruler."""

from __future__ import annotations

import io
import math
import os
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ottag_db.core.types import Polarity, ProgressCallback
from ottag_db.errors import ExportError, UsageError
from ottag_db.printing.geometry import TagGeometry, default_quiet_zone
from ottag_db.printing.output import check_writable
from ottag_db.printing.pdf import MM_TO_PT, draw_tag_pdf, fit_text

__all__ = [
    "PAGE_SIZES_MM",
    "RULER_LENGTH_MM",
    "SheetOptions",
    "SheetReport",
    "SheetTag",
    "parse_length",
    "parse_page",
    "sheet_grid",
    "write_tag_sheet",
]

#: Named page sizes (portrait, width × height in mm). ``parse_page`` also accepts a
#: ``-landscape`` suffix and ``WxH<unit>``.
PAGE_SIZES_MM: dict[str, tuple[float, float]] = {
    "a3": (297.0, 420.0),
    "a4": (210.0, 297.0),
    "a5": (148.0, 210.0),
    "letter": (215.9, 279.4),
    "legal": (215.9, 355.6),
    "tabloid": (279.4, 431.8),
}

#: Length of the printer-check ruler on every page, mm.
RULER_LENGTH_MM = 100.0

_UNITS_MM = {"mm": 1.0, "cm": 10.0, "in": 25.4, "pt": 25.4 / 72.0}
_NUMBER = r"(\d+(?:\.\d*)?|\.\d+)"
_LENGTH_RE = re.compile(rf"^\s*([+-]?)\s*{_NUMBER}\s*([a-zA-Z]*)\s*$")
_PAGE_RE = re.compile(rf"^\s*{_NUMBER}\s*[x×]\s*{_NUMBER}\s*([a-zA-Z]*)\s*$", re.IGNORECASE)

_HEADER_MM = 13.0
_FOOTER_MM = 14.0
_MIN_LABEL_PT = 3.5
_LEADING = 1.2
_MARK_LINE_MM = 0.12


def parse_length(text: str) -> float:
    """Millimetres of a length with a unit: ``"50mm"``, ``"5 cm"``, ``"2in"``, ``"72pt"``.

    Parameters
    ----------
    text : str
        A number and a unit: mm, cm, in or pt.

    Returns
    -------
    float
        The length in mm.

    Raises
    ------
    UsageError
        A missing or unknown unit, or a value that is not > 0.
    """
    match = _LENGTH_RE.match(str(text))
    if not match:
        raise UsageError(f"cannot read the length {text!r}; write a number and a unit, e.g. 50mm, 5cm, 2in")
    sign, number, unit = match.groups()
    if not unit:
        raise UsageError(f"the length {text!r} needs a unit (mm, cm, in or pt), e.g. {number}mm")
    unit = unit.lower()
    if unit not in _UNITS_MM:
        raise UsageError(f"unknown unit {unit!r} in {text!r}; use mm, cm, in or pt")
    value = float(number) * _UNITS_MM[unit]
    if sign == "-" or value <= 0:
        raise UsageError(f"the length {text!r} must be greater than zero")
    return value


def parse_page(text: str) -> tuple[float, float]:
    """Page ``(width, height)`` in mm from ``"A4"``, ``"Letter"``, ``"A4-landscape"``, ``"210x297mm"``.

    Parameters
    ----------
    text : str
        A name (case-insensitive: A3, A4, A5, Letter, Legal, Tabloid), optionally with a
        ``-landscape`` suffix, or ``WxH<unit>``.

    Returns
    -------
    tuple of float
        ``(width, height)`` in mm.

    Raises
    ------
    UsageError
        An unknown name or an unreadable size.
    """
    raw = str(text).strip()
    name = raw.lower()
    landscape = False
    for suffix in ("-landscape", " landscape", ":landscape"):
        if name.endswith(suffix):
            name, landscape = name[: -len(suffix)].strip(), True
    if name in PAGE_SIZES_MM:
        w, h = PAGE_SIZES_MM[name]
        return (h, w) if landscape else (w, h)
    match = _PAGE_RE.match(raw)
    if not match:
        names = ", ".join(n.capitalize() if n[0] != "a" else n.upper() for n in PAGE_SIZES_MM)
        raise UsageError(f"unknown page {text!r}; use {names} or a size such as 210x297mm")
    w_txt, h_txt, unit = match.groups()
    w = parse_length(w_txt + (unit or ""))
    h = parse_length(h_txt + (unit or ""))
    return (w, h)


@dataclass(frozen=True)
class SheetTag:
    """One tag to print: its geometry (any size — the sheet resizes it) and label text.

    ``id_short`` is the short form of the order-type ID shown on the label; ``caption`` an
    optional extra label text (e.g. a dictionary tag number). ``k``, polarity and the printed
    MP (``geom.mp_unit × SheetOptions.tag_size_mm``) come from ``geom``.
    """

    geom: TagGeometry
    id_short: str
    caption: str = ""

    @property
    def k(self) -> int:
        """Number of points."""
        return self.geom.k

    @property
    def polarity(self) -> Polarity:
        """``"normal"`` or ``"inverted"``."""
        return self.geom.polarity


@dataclass(frozen=True)
class SheetOptions:
    """Sheet settings; lengths in mm (see :func:`parse_length` / :func:`parse_page`).

    - ``tag_size_mm``: side of the data area of every tag (what users measure);
    - ``quiet_zone_mm``: quiet-zone width on each side (None: 0.25 × tag size);
    - ``page``: a page name or size text, or ``(width, height)`` in mm;
    - ``margin_mm``: page margin on all sides; ``spacing_mm``: space between tag cells;
    - ``labels``: label under each tag (ID, k, printed MP, polarity);
    - ``cut_marks``: corner marks around each tag's outer (quiet-zone) square;
    - ``filter_summary``: printed in every page header (which tags were selected);
    - ``title``, ``subject``, ``keywords``: PDF metadata (author and creator are "ottag-db");
    - ``label_font_pt``: label font size, shrunk per label down to 3.5 pt to fit the tag width;
    - ``compress``: compress page streams.
    """

    tag_size_mm: float = 40.0
    quiet_zone_mm: float | None = None
    page: str | tuple[float, float] = "A4"
    margin_mm: float = 10.0
    spacing_mm: float = 5.0
    labels: bool = True
    cut_marks: bool = True
    filter_summary: str = ""
    title: str = "Order Type Tags"
    subject: str = "Order Type Tags (fiducial markers) for printing"
    keywords: str = "order type tags, fiducial markers"
    label_font_pt: float = 6.0
    compress: bool = True

    def page_size_mm(self) -> tuple[float, float]:
        """``(width, height)`` of the page in mm."""
        if isinstance(self.page, str):
            return parse_page(self.page)
        w, h = (float(v) for v in self.page)
        if not (w > 0 and h > 0):
            raise UsageError(f"page size must be positive, got {self.page!r}")
        return (w, h)

    def quiet_mm(self) -> float:
        """Quiet-zone width in mm (the default when ``quiet_zone_mm`` is None)."""
        return default_quiet_zone(self.tag_size_mm) if self.quiet_zone_mm is None else self.quiet_zone_mm


@dataclass(frozen=True)
class SheetReport:
    """What :func:`write_tag_sheet` wrote: file, page count and grid (lengths in mm)."""

    path: Path
    pages: int
    tags: int
    columns: int
    rows: int
    page_size_mm: tuple[float, float]
    tag_size_mm: float
    quiet_zone_mm: float
    seconds: float
    bytes_written: int = 0
    per_page: int = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "per_page", self.columns * self.rows)


@dataclass(frozen=True)
class _Grid:
    page: tuple[float, float]
    columns: int
    rows: int
    x0: float  # left edge of first column, mm
    top: float  # top edge of first row, mm
    cell_w: float
    cell_h: float
    pitch_x: float
    pitch_y: float
    total: float
    quiet: float
    label_gap: float
    mark_len: float


def _label_height_mm(options: SheetOptions) -> float:
    return 2 * options.label_font_pt * _LEADING / MM_TO_PT if options.labels else 0.0


def sheet_grid(options: SheetOptions) -> tuple[int, int]:
    """How many tags fit on a page.

    Parameters
    ----------
    options : SheetOptions
        Sheet settings.

    Returns
    -------
    tuple of int
        ``(columns, rows)`` of tags per page.

    Raises
    ------
    ExportError
        Not one tag (or the ruler) fits the page.
    UsageError
        Bad sizes.
    """
    g = _grid(options)
    return g.columns, g.rows


def _grid(options: SheetOptions) -> _Grid:
    for name in ("tag_size_mm", "margin_mm", "spacing_mm", "label_font_pt"):
        value = float(getattr(options, name))
        if not math.isfinite(value) or value < 0 or (name in ("tag_size_mm", "label_font_pt") and value == 0):
            raise UsageError(f"{name.replace('_mm', '').replace('_', ' ')} must be positive, got {value}")
    quiet = options.quiet_mm()
    if not math.isfinite(quiet) or quiet < 0:
        raise UsageError(f"quiet zone must be zero or positive, got {quiet}")
    pw, ph = options.page_size_mm()
    m = options.margin_mm
    total = options.tag_size_mm + 2 * quiet
    avail_w = pw - 2 * m
    sp = options.spacing_mm
    mark_len = min(3.0, 0.45 * sp) if options.cut_marks else 0.0
    top_pad = mark_len + 1.0 if options.cut_marks else 0.0
    avail_h = ph - 2 * m - _HEADER_MM - _FOOTER_MM - top_pad
    if avail_w < RULER_LENGTH_MM:
        raise ExportError(
            f"page {pw:g} × {ph:g} mm with {m:g} mm margins is {avail_w:g} mm wide inside the margins; "
            f"the {RULER_LENGTH_MM:g} mm printer-check ruler needs at least {RULER_LENGTH_MM:g} mm "
            "(use a larger page or smaller margins)"
        )
    label_gap = max(1.0, mark_len + 0.5) if options.labels else 0.0
    cell_w = total
    cell_h = total + (label_gap + _label_height_mm(options) if options.labels else 0.0)
    cols = int((avail_w + sp + 1e-9) // (cell_w + sp))
    rows = int((avail_h + sp + 1e-9) // (cell_h + sp)) if avail_h > 0 else 0
    if cols < 1 or rows < 1:
        raise ExportError(
            f"a tag of {total:g} mm ({options.tag_size_mm:g} mm data area + 2 × {quiet:g} mm quiet zone"
            + (f", plus {cell_h - total:.1f} mm label" if options.labels else "")
            + f") does not fit the {max(avail_w, 0):g} × {max(avail_h, 0):g} mm tag area of the "
            f"{pw:g} × {ph:g} mm page ({m:g} mm margins, header and ruler); use a smaller tag size "
            "or quiet zone, smaller margins, or a larger page"
        )
    grid_w = cols * cell_w + (cols - 1) * sp
    return _Grid(
        page=(pw, ph),
        columns=cols,
        rows=rows,
        x0=m + (avail_w - grid_w) / 2.0,
        top=ph - m - _HEADER_MM - top_pad,
        cell_w=cell_w,
        cell_h=cell_h,
        pitch_x=cell_w + sp,
        pitch_y=cell_h + sp,
        total=total,
        quiet=quiet,
        label_gap=label_gap,
        mark_len=mark_len,
    )


def _draw_ruler(cv: Any, x_mm: float, y_mm: float) -> None:
    """100 mm ruler: baseline, ticks every mm (5 mm and 10 mm longer), cm numbers."""
    k = MM_TO_PT
    cv.setStrokeGray(0)
    cv.setLineWidth(0.15 * k)
    cv.line(x_mm * k, y_mm * k, (x_mm + RULER_LENGTH_MM) * k, y_mm * k)
    path = cv.beginPath()
    for i in range(int(RULER_LENGTH_MM) + 1):
        length = 3.5 if i % 10 == 0 else 2.5 if i % 5 == 0 else 1.5
        path.moveTo((x_mm + i) * k, y_mm * k)
        path.lineTo((x_mm + i) * k, (y_mm + length) * k)
    cv.drawPath(path, stroke=1, fill=0)
    cv.setFillGray(0)
    cv.setFont("Helvetica", 5)
    for i in range(0, int(RULER_LENGTH_MM) + 1, 10):
        cv.drawCentredString((x_mm + i) * k, (y_mm + 4.3) * k, str(i // 10))
    cv.drawString((x_mm + RULER_LENGTH_MM + 2) * k, (y_mm + 1) * k, "cm")


def write_tag_sheet(
    path: str | os.PathLike[str],
    tags: Sequence[SheetTag],
    options: SheetOptions,
    progress: ProgressCallback | None = None,
) -> SheetReport:
    """Write ``tags`` (in the given order) to a multi-page PDF at ``path``.

    Every tag is drawn at ``options.tag_size_mm`` (data-area side) with ``options`` quiet
    zone, in a grid filled row by row from the top left. Each page carries a header (title,
    filter summary, tag size and quiet zone, "print at 100 % scale" note), a footer with a
    100 mm ruler with mm ticks and the page number. Labels: ID short form (and caption),
    ``k``, printed MP in mm and polarity. The PDF is built in memory (reportlab,
    ``invariant=1``, so equal input gives byte-identical output) and written atomically.
    ``progress(done, total)`` is called after each page.

    Parameters
    ----------
    path : str or PathLike
        Output file.
    tags : sequence of SheetTag
        The tags in print order (any size: each is resized to the sheet's).
    options : SheetOptions
        Sheet settings.
    progress : ProgressCallback, optional
        ``progress(done, total)`` in tags, after each page.

    Returns
    -------
    SheetReport
        File, pages, grid, sizes, seconds and bytes written.

    Raises
    ------
    ExportError
        An empty tag list, a tag that does not fit the page or an unwritable path (nothing
        is written then).
    UsageError
        Bad sizes.
    """
    from reportlab.pdfgen.canvas import Canvas

    started = time.perf_counter()
    out = Path(path)
    if not tags:
        raise ExportError("no tags to write: the selection is empty (no PDF written)")
    grid = _grid(options)
    check_writable(out)
    quiet = grid.quiet
    size = options.tag_size_mm
    per_page = grid.columns * grid.rows
    n_pages = -(-len(tags) // per_page)
    k = MM_TO_PT
    pw, ph = grid.page
    buf = io.BytesIO()
    c = Canvas(buf, pagesize=(pw * k, ph * k), invariant=1, pageCompression=1 if options.compress else 0)
    c.setTitle(options.title)
    c.setAuthor("ottag-db")
    c.setSubject(options.subject)
    c.setCreator("ottag-db")
    c.setKeywords(options.keywords)
    m = options.margin_mm
    text_w = (pw - 2 * m) * k
    info = (
        f"Tag size {size:g} mm (side of the data area), quiet zone {quiet:g} mm. "
        "Print at 100 % scale (actual size, no 'fit to page'); check with the 100 mm ruler below."
    )
    summary = options.filter_summary.strip() or "all selected tags"
    label_w = grid.total * k
    font_pt = options.label_font_pt
    line_mm = font_pt * _LEADING / k
    for page in range(n_pages):
        # header
        c.setFillGray(0)
        title, tsize = fit_text(options.title, "Helvetica-Bold", 10, text_w, 5)
        c.setFont("Helvetica-Bold", tsize)
        c.drawString(m * k, (ph - m - 3.5) * k, title)
        c.setFont("Helvetica", 7)
        right = f"page {page + 1} / {n_pages}"
        c.drawRightString((pw - m) * k, (ph - m - 3.5) * k, right)
        line, lsize = fit_text(f"Selection: {summary}", "Helvetica", 7, text_w, 4)
        c.setFont("Helvetica", lsize)
        c.drawString(m * k, (ph - m - 7.5) * k, line)
        line, lsize = fit_text(info, "Helvetica", 7, text_w, 4)
        c.setFont("Helvetica", lsize)
        c.drawString(m * k, (ph - m - 11) * k, line)
        # footer: ruler and note
        _draw_ruler(c, m, m + 5.0)
        c.setFillGray(0)
        c.setFont("Helvetica", 6)
        c.drawString(
            m * k,
            (m + 1.0) * k,
            f"Printer check: this ruler must measure exactly {RULER_LENGTH_MM:g} mm; "
            f"otherwise the tags are not {size:g} mm.",
        )
        c.drawRightString((pw - m) * k, (m + 1.0) * k, "ottag-db")
        # tags
        first = page * per_page
        page_tags = tags[first : first + per_page]
        if options.cut_marks and grid.mark_len > 0:
            c.setStrokeGray(0)
            c.setLineWidth(_MARK_LINE_MM * k)
            marks = c.beginPath()
        for n, tag in enumerate(page_tags):
            row, col = divmod(n, grid.columns)
            x = grid.x0 + col * grid.pitch_x
            y_top = grid.top - row * grid.pitch_y
            y = y_top - grid.total
            g = tag.geom
            if g.tag_size != size or g.quiet_zone != quiet:
                g = g.resized(size, quiet)
            draw_tag_pdf(c, g, x, y)
            if options.cut_marks and grid.mark_len > 0:
                ml, t = grid.mark_len, grid.total
                for cx, cy, sx, sy in ((x, y, -1, -1), (x + t, y, 1, -1), (x, y + t, -1, 1), (x + t, y + t, 1, 1)):
                    marks.moveTo(cx * k, cy * k)
                    marks.lineTo((cx + sx * ml) * k, cy * k)
                    marks.moveTo(cx * k, cy * k)
                    marks.lineTo(cx * k, (cy + sy * ml) * k)
            if options.labels:
                c.setFillGray(0)
                cx = (x + grid.total / 2.0) * k
                base = y - grid.label_gap - line_mm * 0.8
                first_line = tag.id_short + (f"  {tag.caption}" if tag.caption else "")
                text, fs = fit_text(first_line, "Helvetica-Bold", font_pt, label_w, _MIN_LABEL_PT)
                c.setFont("Helvetica-Bold", fs)
                c.drawCentredString(cx, base * k, text)
                second = f"k={g.k}  MP {g.mp_unit * size:.2f} mm  {g.polarity}"
                text, fs = fit_text(second, "Helvetica", font_pt, label_w, _MIN_LABEL_PT)
                c.setFont("Helvetica", fs)
                c.drawCentredString(cx, (base - line_mm) * k, text)
        if options.cut_marks and grid.mark_len > 0:
            c.drawPath(marks, stroke=1, fill=0)
        c.showPage()
        if progress is not None:
            progress(min(first + per_page, len(tags)), len(tags))
    c.save()
    data = buf.getvalue()
    try:
        out.write_bytes(data)
    except OSError as exc:
        raise ExportError(f"cannot write the tag sheet to {out}: {exc.strerror or exc}") from exc
    return SheetReport(
        path=out,
        pages=n_pages,
        tags=len(tags),
        columns=grid.columns,
        rows=grid.rows,
        page_size_mm=(pw, ph),
        tag_size_mm=size,
        quiet_zone_mm=quiet,
        seconds=time.perf_counter() - started,
        bytes_written=len(data),
    )
