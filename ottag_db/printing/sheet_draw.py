"""Drawing a sheet page on a reportlab canvas: header, footer with the ruler, tags, marks, labels.

Positions come from :mod:`ottag_db.printing.sheet_layout`; :func:`ottag_db.printing.sheet.write_tag_sheet`
calls these per page.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ottag_db.printing.pdf import MM_TO_PT, draw_tag_pdf, fit_text
from ottag_db.printing.sheet_layout import FOOTER_MM, LEADING, MIN_LABEL_PT, RULER_LENGTH_MM, SheetLayout

if TYPE_CHECKING:
    from ottag_db.printing.sheet import SheetOptions, SheetTag

__all__ = ["draw_page_furniture", "draw_page_tags", "draw_ruler", "label_texts"]

_MARK_LINE_MM = 0.12


def label_texts(tag: SheetTag, size: float) -> tuple[str, str]:
    """The two parts of a tag's label: ID short form (and caption), then k, printed MP, polarity."""
    first = tag.id_short + (f"  {tag.caption}" if tag.caption else "")
    return first, f"k={tag.k}  MP {tag.geom.mp_unit * size:.2f} mm  {tag.polarity}"


def draw_ruler(cv: Any, x_mm: float, y_mm: float) -> None:
    """Draw the 100 mm printer-check ruler: baseline, ticks every mm (5 mm and 10 mm longer), cm numbers.

    Parameters
    ----------
    cv : reportlab.pdfgen.canvas.Canvas
        The page to draw on (PDF user space, origin bottom-left).
    x_mm, y_mm : float
        Left end of the baseline, mm from the page's bottom-left corner.
    """
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


def draw_page_furniture(c: Any, options: SheetOptions, grid: SheetLayout, page: int, n_pages: int) -> None:
    """Header (title, page number, selection, sizes and print note) and footer (ruler, note)."""
    k = MM_TO_PT
    pw, ph = grid.page
    m = options.margin_mm
    size = options.tag_size_mm
    text_w = (pw - 2 * m) * k
    top = ph - m
    c.setFillGray(0)
    right = f"page {page + 1} / {n_pages}"
    title, tsize = fit_text(options.title, "Helvetica-Bold", 9, text_w - 30 * k, 5)
    c.setFont("Helvetica-Bold", tsize)
    c.drawString(m * k, (top - 3.2) * k, title)
    c.setFont("Helvetica", 7)
    c.drawRightString((pw - m) * k, (top - 3.2) * k, right)
    summary = options.filter_summary.strip() or "all selected tags"
    info = (
        f"Tag size {size:g} mm (side of the data area), quiet zone {grid.quiet:g} mm. "
        "Print at 100 % scale (actual size, no 'fit to page'); check with the 100 mm ruler below."
    )
    for text, y in ((f"Selection: {summary}", 6.4), (info, 9.4)):
        line, lsize = fit_text(text, "Helvetica", 6.5, text_w, 4)
        c.setFont("Helvetica", lsize)
        c.drawString(m * k, (top - y) * k, line)
    note = (
        f"Printer check: this ruler must measure exactly {RULER_LENGTH_MM:g} mm;",
        f"otherwise the tags are not {size:g} mm.",
    )
    c.setFont("Helvetica", 6)
    if grid.footer_mm == FOOTER_MM:  # note beside the ruler
        draw_ruler(c, m, m + 1.0)
        c.setFillGray(0)
        x = m + RULER_LENGTH_MM + 8.0
        width = (pw - m - x - 10.0) * k
        for text, y in zip(note, (m + 4.2, m + 1.6), strict=True):
            line, lsize = fit_text(text, "Helvetica", 6, width, 4)
            c.setFont("Helvetica", lsize)
            c.drawString(x * k, y * k, line)
        c.setFont("Helvetica", 6)
    else:
        draw_ruler(c, m, m + 5.0)
        c.setFillGray(0)
        line, lsize = fit_text(" ".join(note), "Helvetica", 6, text_w - 12 * k, 4)
        c.setFont("Helvetica", lsize)
        c.drawString(m * k, (m + 1.0) * k, line)
        c.setFont("Helvetica", 6)
    c.drawRightString((pw - m) * k, (m + 1.6) * k, "ottag-db")


def draw_page_tags(c: Any, page_tags: Sequence[SheetTag], options: SheetOptions, grid: SheetLayout) -> None:
    """Quiet zones first (shared zones overlap harmlessly), then data areas, marks and labels."""
    k = MM_TO_PT
    size, quiet = options.tag_size_mm, grid.quiet
    geoms = []
    for tag in page_tags:
        g = tag.geom
        geoms.append(g if g.tag_size == size and g.quiet_zone == quiet else g.resized(size, quiet))
    origins = [grid.tag_origin(n) for n in range(len(page_tags))]
    if quiet > 0:
        for g, (x, y) in zip(geoms, origins, strict=True):
            c.setFillGray(g.tones()[0] / 255.0)
            c.rect(x * k, y * k, grid.total * k, grid.total * k, stroke=0, fill=1)
    for g, (x, y) in zip(geoms, origins, strict=True):
        draw_tag_pdf(c, g, x, y, quiet_zone=False)
    if grid.mark_len > 0:
        c.setStrokeGray(0)
        c.setLineWidth(_MARK_LINE_MM * k)
        marks = c.beginPath()
        ml, t = grid.mark_len, grid.total
        for x, y in origins:
            for cx, cy, sx, sy in ((x, y, -1, -1), (x + t, y, 1, -1), (x, y + t, -1, 1), (x + t, y + t, 1, 1)):
                marks.moveTo(cx * k, cy * k)
                marks.lineTo((cx + sx * ml) * k, cy * k)
                marks.moveTo(cx * k, cy * k)
                marks.lineTo(cx * k, (cy + sy * ml) * k)
        c.drawPath(marks, stroke=1, fill=0)
    if grid.label_lines:
        c.setFillGray(0)
        for tag, (x, y) in zip(page_tags, origins, strict=True):
            _draw_label(c, label_texts(tag, size), x + grid.total / 2.0, y - grid.label_gap, options, grid)


def _draw_label(
    c: Any, texts: tuple[str, str], cx_mm: float, top_mm: float, options: SheetOptions, grid: SheetLayout
) -> None:
    """One label centred at ``cx_mm`` with its first line's top at ``top_mm`` (page mm, y up)."""
    from reportlab.pdfbase.pdfmetrics import stringWidth

    k = MM_TO_PT
    font_pt = options.label_font_pt
    line_mm = font_pt * LEADING / k
    width = grid.label_width * k
    base = (top_mm - line_mm * 0.8) * k
    first, second = texts
    if grid.label_lines == 1:  # bold ID part, then the details, shrunk together to fit
        wb, wr = stringWidth(first, "Helvetica-Bold", font_pt), stringWidth("  " + second, "Helvetica", font_pt)
        fs = min(font_pt, font_pt * width / (wb + wr))
        x = cx_mm * k - (wb + wr) * fs / font_pt / 2.0
        c.setFont("Helvetica-Bold", fs)
        c.drawString(x, base, first)
        c.setFont("Helvetica", fs)
        c.drawString(x + wb * fs / font_pt, base, "  " + second)
        return
    text, fs = fit_text(first, "Helvetica-Bold", font_pt, width, MIN_LABEL_PT)
    c.setFont("Helvetica-Bold", fs)
    c.drawCentredString(cx_mm * k, base, text)
    text, fs = fit_text(second, "Helvetica", font_pt, width, MIN_LABEL_PT)
    c.setFont("Helvetica", fs)
    c.drawCentredString(cx_mm * k, base - line_mm * k, text)
