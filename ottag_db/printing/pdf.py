"""PDF drawing of a tag on a reportlab canvas (the sheets in :mod:`ottag_db.printing.sheet` use it)."""

from __future__ import annotations

from typing import Any

from ottag_db.printing.geometry import TagGeometry

__all__ = ["MM_TO_PT", "draw_tag_pdf", "fit_text"]

#: Points per millimetre (PDF user space unit is 1/72 inch).
MM_TO_PT = 72.0 / 25.4


def draw_tag_pdf(canvas: Any, geom: TagGeometry, x_mm: float, y_mm: float, *, quiet_zone: bool = True) -> None:
    """Draw the tag on a reportlab canvas with its lower-left corner at (``x_mm``, ``y_mm``).

    Positions are page coordinates in mm from the page's lower-left corner (PDF y-up); the
    whole tag, quiet zone included, covers ``total_size`` mm. Points are flipped (unit
    y down → PDF y up) so the printed tag reads like the raster and the SVG. Three fills:
    quiet-zone square (skipped with ``quiet_zone=False`` — e.g. white on white paper), data
    square (a ``re`` of side ``tag_size``), and one path with all triangles.

    Parameters
    ----------
    canvas : reportlab.pdfgen.canvas.Canvas
        The canvas to draw on (user space in points).
    geom : TagGeometry
        The tag; ``tag_size`` and ``quiet_zone`` in mm.
    x_mm, y_mm : float
        Lower-left corner of the whole tag on the page, mm from the page's lower-left corner.
    quiet_zone : bool
        Fill the quiet-zone square.
    """
    quiet_tone, data_tone, tri_tone = geom.tones()
    k = MM_TO_PT
    total = geom.total_size * k
    x0, y0 = x_mm * k, y_mm * k
    q = geom.quiet_zone * k
    s = geom.tag_size * k
    if quiet_zone and geom.quiet_zone > 0:
        canvas.setFillGray(quiet_tone / 255.0)
        canvas.rect(x0, y0, total, total, stroke=0, fill=1)
    canvas.setFillGray(data_tone / 255.0)
    canvas.rect(x0 + q, y0 + q, s, s, stroke=0, fill=1)
    dx, dy = x0 + q, y0 + q + s
    pts = [(dx + s * u, dy - s * v) for u, v in geom.points]
    path = canvas.beginPath()
    for a, b, c in geom.triangles:
        path.moveTo(*pts[a])
        path.lineTo(*pts[b])
        path.lineTo(*pts[c])
        path.close()
    canvas.setFillGray(tri_tone / 255.0)
    canvas.drawPath(path, stroke=0, fill=1)


def fit_text(text: str, font: str, size: float, width_pt: float, min_size: float) -> tuple[str, float]:
    """Shrink ``size`` (not below ``min_size``), then truncate with "...", to fit ``width_pt``.

    Parameters
    ----------
    text : str
        The text.
    font : str
        A reportlab standard font name, e.g. ``"Helvetica"``.
    size, min_size : float
        Wanted and smallest font size, points.
    width_pt : float
        Available width, points.

    Returns
    -------
    tuple of (str, float)
        The text (maybe truncated) and the font size to draw it with.
    """
    from reportlab.pdfbase.pdfmetrics import stringWidth

    w = stringWidth(text, font, size)
    if w <= width_pt:
        return text, size
    size = max(min_size, size * width_pt / w)
    if stringWidth(text, font, size) <= width_pt:
        return text, size
    lo, hi = 0, len(text)
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if stringWidth(text[:mid] + "...", font, size) <= width_pt:
            lo = mid
        else:
            hi = mid - 1
    return text[:lo] + "...", size
