"""Printable PDF tag sheets: tags in a grid with labels, cut marks, print notes and a test ruler."""

from __future__ import annotations

import io
import os
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ottag_db.core.types import Polarity, ProgressCallback
from ottag_db.errors import ExportError, UsageError
from ottag_db.printing.geometry import TagGeometry, default_quiet_zone
from ottag_db.printing.output import check_writable
from ottag_db.printing.pdf import MM_TO_PT
from ottag_db.printing.sheet_draw import draw_page_furniture, draw_page_tags, label_texts
from ottag_db.printing.sheet_layout import RULER_LENGTH_MM, SheetLayout, plan_sheet

__all__ = [
    "PAGE_SIZES_MM",
    "RULER_LENGTH_MM",
    "SheetLayout",
    "SheetOptions",
    "SheetReport",
    "SheetTag",
    "parse_length",
    "parse_page",
    "sheet_grid",
    "sheet_layout",
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

_UNITS_MM = {"mm": 1.0, "cm": 10.0, "in": 25.4, "pt": 25.4 / 72.0}
_NUMBER = r"(\d+(?:\.\d*)?|\.\d+)"
_LENGTH_RE = re.compile(rf"^\s*([+-]?)\s*{_NUMBER}\s*([a-zA-Z]*)\s*$")
_PAGE_RE = re.compile(rf"^\s*{_NUMBER}\s*[x×]\s*{_NUMBER}\s*([a-zA-Z]*)\s*$", re.IGNORECASE)


def parse_length(text: str, *, allow_zero: bool = False) -> float:
    """Millimetres of a length with a unit: ``"50mm"``, ``"5 cm"``, ``"2in"``, ``"72pt"``.

    Parameters
    ----------
    text : str
        A number and a unit: mm, cm, in or pt.
    allow_zero : bool
        Accept 0 (e.g. no spacing between tags).

    Returns
    -------
    float
        The length in mm.

    Raises
    ------
    UsageError
        A missing or unknown unit, or a value that is not > 0 (≥ 0 with ``allow_zero``).
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
    if (sign == "-" and value != 0) or value < 0 or (value == 0 and not allow_zero):
        raise UsageError(f"the length {text!r} must be greater than zero" + (" or zero" if allow_zero else ""))
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
    - ``margin_mm``: page margin on all sides; ``spacing_mm``: extra paper between neighbouring
      tags beyond their quiet zones (at least 5 mm with cut marks);
    - ``pack``: neighbours of one polarity share their quiet zones (a sheet of one polarity
      without cut marks; see :mod:`ottag_db.printing.sheet_layout`);
    - ``labels``: label under each tag (ID, k, printed MP, polarity), outside every quiet zone;
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
    spacing_mm: float = 0.0
    labels: bool = True
    cut_marks: bool = True
    filter_summary: str = ""
    title: str = "Order Type Tags"
    subject: str = "Order Type Tags (fiducial markers) for printing"
    keywords: str = "order type tags, fiducial markers"
    label_font_pt: float = 6.0
    compress: bool = True
    pack: bool = True

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
    """What :func:`write_tag_sheet` wrote: file, page count and grid (lengths in mm).

    ``per_page`` = ``columns × rows``; ``packed``: neighbouring tags share quiet zones.
    """

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
    packed: bool = False
    per_page: int = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "per_page", self.columns * self.rows)


def sheet_layout(options: SheetOptions, tags: Sequence[SheetTag] | None = None) -> SheetLayout:
    """The page grid :func:`write_tag_sheet` uses for ``tags``.

    Parameters
    ----------
    options : SheetOptions
        Sheet settings.
    tags : sequence of SheetTag, optional
        The sheet's tags: one polarity lets neighbours share quiet zones, short labels go on
        one line. None: the grid that holds any tags (no sharing, two-line labels).

    Returns
    -------
    SheetLayout
        Columns, rows, positions and label room (see :mod:`ottag_db.printing.sheet_layout`).

    Raises
    ------
    ExportError
        Not one tag (or the ruler) fits the page.
    UsageError
        Bad sizes.
    """
    if tags is None:
        return plan_sheet(options)
    labels = [label_texts(t, options.tag_size_mm) for t in tags] if options.labels else None
    return plan_sheet(options, {t.polarity for t in tags}, labels)


def sheet_grid(options: SheetOptions, tags: Sequence[SheetTag] | None = None) -> tuple[int, int]:
    """How many tags fit on a page.

    Parameters
    ----------
    options : SheetOptions
        Sheet settings.
    tags : sequence of SheetTag, optional
        The sheet's tags (see :func:`sheet_layout`); None: the grid that holds any tags.

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
    g = sheet_layout(options, tags)
    return g.columns, g.rows


def write_tag_sheet(
    path: str | os.PathLike[str],
    tags: Sequence[SheetTag],
    options: SheetOptions,
    progress: ProgressCallback | None = None,
) -> SheetReport:
    """Write ``tags`` (in the given order) to a multi-page PDF at ``path``.

    Every tag is drawn at ``options.tag_size_mm`` (data-area side) with ``options`` quiet
    zone, in the grid of :func:`sheet_layout` filled row by row from the top left: as many
    tags as fit, neighbours of one polarity sharing their quiet zones, labels (ID short form
    and caption, ``k``, printed MP in mm, polarity) under each tag and outside every quiet
    zone. Each page carries a header (title, filter summary, tag size and quiet zone,
    "print at 100 % scale" note) and a footer with a 100 mm ruler with mm ticks and the page
    number. The PDF is built in memory (reportlab, ``invariant=1``, so equal input gives
    byte-identical output) and written atomically. ``progress(done, total)`` is called
    after each page.

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
    grid = sheet_layout(options, tags)
    check_writable(out)
    size = options.tag_size_mm
    per_page = grid.per_page
    n_pages = -(-len(tags) // per_page)
    pw, ph = grid.page
    buf = io.BytesIO()
    c = Canvas(buf, pagesize=(pw * MM_TO_PT, ph * MM_TO_PT), invariant=1, pageCompression=int(options.compress))
    c.setTitle(options.title)
    c.setAuthor("ottag-db")
    c.setSubject(options.subject)
    c.setCreator("ottag-db")
    c.setKeywords(options.keywords)
    for page in range(n_pages):
        draw_page_furniture(c, options, grid, page, n_pages)
        first = page * per_page
        draw_page_tags(c, tags[first : first + per_page], options, grid)
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
        quiet_zone_mm=grid.quiet,
        seconds=time.perf_counter() - started,
        bytes_written=len(data),
        packed=grid.packed,
    )
