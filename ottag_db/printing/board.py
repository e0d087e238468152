"""Calibration boards on paper: a grid of tags on one page (layout, fit check, PDF drawing).

A board is ``rows × cols`` data areas of side ``tag_size`` with ``spacing`` of paper between
neighbouring data areas (the white gap is every tag's quiet zone); the same gap surrounds the
grid. Board coordinates are mm with the origin at the top-left corner of the first tag's data
area, x right, y down (screen convention). The page carries a header (title, what the board
holds, print note), a label under each tag (outside the data areas) and the sheets' 100 mm
printer-check ruler (:mod:`ottag_db.printing.sheet`).
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ottag_db.errors import ExportError, UsageError
from ottag_db.printing.geometry import TagGeometry
from ottag_db.printing.output import check_writable
from ottag_db.printing.pdf import MM_TO_PT, draw_tag_pdf, fit_text
from ottag_db.printing.sheet_draw import draw_ruler
from ottag_db.printing.sheet_layout import RULER_LENGTH_MM

__all__ = ["BOARD_MARGIN_MM", "BoardPage", "BoardPlacement", "DistortedCamera", "board_page", "write_board_pdf"]

#: Page margin of a board, mm.
BOARD_MARGIN_MM = 10.0
_HEADER_MM = 13.0
_FOOTER_MM = 14.0


@dataclass(frozen=True)
class BoardPage:
    """Where a board sits on its page (mm).

    ``origin_mm`` is the board origin (top-left corner of the first tag's data area) in page
    coordinates from the page's top-left corner, x right, y down; ``pitch_mm`` the distance
    between neighbouring data areas' left (top) edges: ``tag_size_mm + spacing_mm``.
    """

    page_mm: tuple[float, float]
    rows: int
    cols: int
    tag_size_mm: float
    spacing_mm: float
    origin_mm: tuple[float, float]

    @property
    def pitch_mm(self) -> float:
        """Data-area pitch, mm."""
        return self.tag_size_mm + self.spacing_mm

    @property
    def size_mm(self) -> tuple[float, float]:
        """Width and height of the grid of data areas, mm."""
        return (
            self.cols * self.tag_size_mm + (self.cols - 1) * self.spacing_mm,
            self.rows * self.tag_size_mm + (self.rows - 1) * self.spacing_mm,
        )

    def data_area_mm(self, row: int, col: int) -> tuple[float, float]:
        """Top-left corner of the data area of tag (``row``, ``col``) in board coordinates, mm."""
        return (col * self.pitch_mm, row * self.pitch_mm)


@dataclass(frozen=True)
class BoardPlacement:
    """One tag to draw on a board: its geometry (any size; redrawn at the board's) and label."""

    row: int
    col: int
    geom: TagGeometry
    label: str


def _max_count(avail: float, size: float, spacing: float) -> int:
    """How many data areas of ``size`` with ``spacing`` between and around them fit ``avail``."""
    return max(0, int((avail - spacing + 1e-9) // (size + spacing)))


def board_page(page_mm: tuple[float, float], rows: int, cols: int, tag_size_mm: float, spacing_mm: float) -> BoardPage:
    """Lay a ``rows × cols`` board out on a page, centred in the space between header and ruler.

    Parameters
    ----------
    page_mm : tuple of float
        Page width and height, mm.
    rows, cols : int
        Grid size (≥ 1 each).
    tag_size_mm : float
        Side of each black data area, mm.
    spacing_mm : float
        Paper between neighbouring data areas (and around the grid), mm.

    Returns
    -------
    BoardPage
        The layout.

    Raises
    ------
    UsageError
        Non-positive sizes or counts.
    ExportError
        The board does not fit the page; the message names the largest grid that does.
    """
    if rows < 1 or cols < 1:
        raise UsageError(f"a board needs at least 1 row and 1 column, got {rows} × {cols}")
    for name, value in (("tag size", tag_size_mm), ("spacing", spacing_mm)):
        if not math.isfinite(value) or value <= 0:
            raise UsageError(f"{name} must be greater than zero, got {value:g} mm")
    pw, ph = page_mm
    m = BOARD_MARGIN_MM
    avail_w = pw - 2 * m
    avail_h = ph - 2 * m - _HEADER_MM - _FOOTER_MM
    if avail_w < RULER_LENGTH_MM:
        raise ExportError(
            f"the {pw:g} × {ph:g} mm page is too narrow for the {RULER_LENGTH_MM:g} mm printer-check ruler; "
            "use a larger page"
        )
    need_w = cols * tag_size_mm + (cols + 1) * spacing_mm
    need_h = rows * tag_size_mm + (rows + 1) * spacing_mm
    if need_w > avail_w + 1e-9 or need_h > avail_h + 1e-9:
        max_c = _max_count(avail_w, tag_size_mm, spacing_mm)
        max_r = _max_count(avail_h, tag_size_mm, spacing_mm)
        fits = (
            f"the largest board that fits is {max_r} rows × {max_c} columns"
            if max_r and max_c
            else "not even one tag fits"
        )
        turned = ""
        if (
            _max_count(ph - 2 * m, tag_size_mm, spacing_mm) >= cols
            and _max_count(pw - 2 * m - _HEADER_MM - _FOOTER_MM, tag_size_mm, spacing_mm) >= rows
        ):
            turned = " (it fits the page in landscape: add -landscape to the page name)"
        raise ExportError(
            f"a {rows} × {cols} board of {tag_size_mm:g} mm tags with {spacing_mm:g} mm spacing needs "
            f"{need_w:g} × {need_h:g} mm; the {pw:g} × {ph:g} mm page has {avail_w:g} × {avail_h:g} mm inside "
            f"its margins, header and ruler: {fits} at these sizes{turned}; use fewer rows/columns, smaller "
            "tags or spacing, or a larger page"
        )
    grid_w = need_w - 2 * spacing_mm
    grid_h = need_h - 2 * spacing_mm
    origin = (m + (avail_w - grid_w) / 2.0, m + _HEADER_MM + (avail_h - grid_h) / 2.0)
    return BoardPage(
        page_mm=(float(pw), float(ph)),
        rows=rows,
        cols=cols,
        tag_size_mm=float(tag_size_mm),
        spacing_mm=float(spacing_mm),
        origin_mm=origin,
    )


def write_board_pdf(
    path: str | os.PathLike[str],
    layout: BoardPage,
    tags: Sequence[BoardPlacement],
    *,
    title: str = "Order Type Tag calibration board",
    summary: str = "",
) -> int:
    """Write the board as a one-page vector PDF in exact physical size.

    Each data area is drawn with :func:`ottag_db.printing.pdf.draw_tag_pdf` at the board's
    tag size; normal tags need no quiet-zone fill (white paper), inverted ones get a black
    quiet zone of at most 0.3 × spacing so neighbours never touch. Each label is centred in
    the gap under its tag. Equal input gives byte-identical output (reportlab ``invariant``).

    Parameters
    ----------
    path : str or PathLike
        The PDF file (written atomically from memory).
    layout : BoardPage
        From :func:`board_page`.
    tags : sequence of BoardPlacement
        The tags with their grid cells.
    title : str
        Header title and PDF title.
    summary : str
        Second header line: what the board holds.

    Returns
    -------
    int
        Bytes written.

    Raises
    ------
    ExportError
        The file cannot be written.
    """
    from reportlab.pdfgen.canvas import Canvas

    out = Path(path)
    check_writable(out)
    k = MM_TO_PT
    pw, ph = layout.page_mm
    m = BOARD_MARGIN_MM
    s, sp = layout.tag_size_mm, layout.spacing_mm
    buf = io.BytesIO()
    c = Canvas(buf, pagesize=(pw * k, ph * k), invariant=1, pageCompression=1)
    c.setTitle(title)
    c.setAuthor("ottag-db")
    c.setCreator("ottag-db")
    c.setSubject("Order Type Tags calibration board")
    text_w = (pw - 2 * m) * k
    c.setFillGray(0)
    line, size = fit_text(title, "Helvetica-Bold", 10, text_w, 5)
    c.setFont("Helvetica-Bold", size)
    c.drawString(m * k, (ph - m - 3.5) * k, line)
    for text, y in (
        (summary, ph - m - 7.5),
        (
            f"Tag size {s:g} mm (side of each black square), pitch {layout.pitch_mm:g} mm. Print at 100 % scale "
            "(actual size, no 'fit to page'); mount flat.",
            ph - m - 11,
        ),
    ):
        line, size = fit_text(text, "Helvetica", 7, text_w, 4)
        c.setFont("Helvetica", size)
        c.drawString(m * k, y * k, line)
    ox, oy = layout.origin_mm
    font_pt = min(6.0, 0.45 * sp * k)
    for t in tags:
        x_mm, y_mm = layout.data_area_mm(t.row, t.col)
        left, top = ox + x_mm, oy + y_mm
        quiet = min(0.25 * s, 0.3 * sp) if t.geom.inverted else 0.0
        g = t.geom.resized(s, quiet)
        draw_tag_pdf(c, g, left - quiet, ph - top - s - quiet, quiet_zone=quiet > 0)
        if t.label and font_pt >= 2.0:
            text, fs = fit_text(t.label, "Helvetica", font_pt, (s + 0.8 * sp) * k, 2.0)
            c.setFillGray(0)
            c.setFont("Helvetica", fs)
            base = ph - (top + s + quiet + (sp - quiet) / 2.0) - 0.35 * fs / k
            c.drawCentredString((left + s / 2.0) * k, base * k, text)
    draw_ruler(c, m, m + 5.0)
    c.setFillGray(0)
    c.setFont("Helvetica", 6)
    span = (layout.cols - 1) * layout.pitch_mm
    check = f"; left edges of the first and last column: {span:g} mm apart" if layout.cols > 1 else ""
    c.drawString(m * k, (m + 1.0) * k, f"Printer check: the ruler must measure exactly {RULER_LENGTH_MM:g} mm{check}.")
    c.drawRightString((pw - m) * k, (m + 1.0) * k, "ottag-db")
    c.showPage()
    c.save()
    data = buf.getvalue()
    try:
        out.write_bytes(data)
    except OSError as exc:
        raise ExportError(f"cannot write the board to {out}: {exc.strerror or exc}") from exc
    return len(data)


class DistortedCamera:
    """A pinhole camera with OpenCV lens distortion that photographs flat pages (synthetic
    calibration views for tests and benchmarks).

    The undistorted ray of every (supersampled) pixel is computed once; :meth:`render` then maps
    the rays onto the page plane of one pose and samples a page raster, so the frame carries
    the lens distortion exactly (the inverse map, as ``cv2.initUndistortRectifyMap`` builds
    for the opposite direction).

    Parameters
    ----------
    camera_matrix : array_like
        3×3 intrinsics, px (origin at the centre of the top-left pixel).
    dist_coeffs : array_like
        OpenCV distortion coefficients (k1, k2, p1, p2[, k3 …]).
    shape : tuple of int
        Frame height and width, px.
    supersampling : int
        Rays per pixel along each axis; the frame is reduced by area averaging.
    """

    def __init__(self, camera_matrix: Any, dist_coeffs: Any, shape: tuple[int, int], supersampling: int = 2):
        import cv2
        import numpy as np

        self.camera_matrix = np.asarray(camera_matrix, dtype=np.float64)
        self.dist_coeffs = np.asarray(dist_coeffs, dtype=np.float64).ravel()
        self.shape = (int(shape[0]), int(shape[1]))
        self.supersampling = int(supersampling)
        h, w = self.shape
        ss = self.supersampling
        ys, xs = np.mgrid[0 : h * ss, 0 : w * ss].astype(np.float64)
        pix = np.stack([(xs + 0.5) / ss - 0.5, (ys + 0.5) / ss - 0.5], axis=-1).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        und = cv2.undistortPoints(pix, self.camera_matrix, self.dist_coeffs, None, None, None, crit)
        self._rays = np.asarray(und, dtype=np.float64).reshape(h * ss, w * ss, 2)

    def render(
        self,
        page: Any,
        px_per_mm: float | tuple[float, float],
        origin_mm: tuple[float, float],
        rvec: Any,
        tvec: Any,
        rng: Any,
        *,
        blur: float = 0.0,
        noise: float = 0.0,
        background: int = 120,
    ) -> Any:
        """Photograph ``page`` (a grey raster) with the board at pose (``rvec``, ``tvec``).

        Parameters
        ----------
        page : numpy.ndarray
            ``(H, W)`` uint8 page raster; pixel ``(i, j)`` covers ``[j, j + 1) / px_per_mm`` mm.
        px_per_mm : float or tuple of float
            Raster resolution, or ``(x, y)`` resolutions (a rasterizer that rounds the page
            size up to whole pixels stretches it slightly).
        origin_mm : tuple of float
            Board origin on the page, mm from the page's top-left corner (x right, y down).
        rvec, tvec : array_like
            Board → camera pose (Rodrigues vector; translation in mm), board coordinates in mm
            with z = 0 on the page.
        rng : numpy.random.Generator
            Draws the noise.
        blur : float
            Gaussian blur σ, px.
        noise : float
            Gaussian noise σ, grey levels.
        background : int
            Grey level off the page.

        Returns
        -------
        numpy.ndarray
            ``(h, w)`` uint8 frame.
        """
        import cv2
        import numpy as np

        rot, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))
        t = np.asarray(tvec, dtype=np.float64).ravel()
        plane = np.c_[rot[:, 0], rot[:, 1], t]  # board (X, Y, 1) → camera
        inv = np.linalg.inv(plane)
        r = self._rays
        q = r[..., 0, None] * inv[:, 0] + r[..., 1, None] * inv[:, 1] + inv[:, 2]
        w = q[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            bx = np.where(w > 0, q[..., 0] / w, -1e6)
            by = np.where(w > 0, q[..., 1] / w, -1e6)
        sx, sy = (px_per_mm, px_per_mm) if isinstance(px_per_mm, (int, float)) else px_per_mm
        mapx = ((origin_mm[0] + bx) * sx - 0.5).astype(np.float32)
        mapy = ((origin_mm[1] + by) * sy - 0.5).astype(np.float32)
        big = cv2.remap(page, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=background)
        h, wd = self.shape
        img = cv2.resize(big, (wd, h), interpolation=cv2.INTER_AREA).astype(np.float32)
        if blur > 0:
            img = np.asarray(cv2.GaussianBlur(img, (0, 0), blur), dtype=np.float32)
        if noise > 0:
            img += rng.normal(0, noise, img.shape).astype(np.float32)
        return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def calibration_poses(
    board_size_mm: tuple[float, float],
    camera_matrix: Any,
    image_size: tuple[int, int],
    count: int,
    rng: Any,
    *,
    tilt_deg: tuple[float, float] = (20.0, 45.0),
    fill: float = 0.6,
) -> list[tuple[Any, Any]]:
    """Board poses for synthetic calibration views: tilted in every direction, spread over the frame.

    View ``i`` tilts the board by an angle drawn from ``tilt_deg`` about an in-plane axis at
    ``i · 360° / count`` (plus jitter), turns it by up to ±30° in its plane, and puts its centre
    on one of 9 frame positions (centre, edges, corners, in turn), at the distance where the
    board's diagonal spans ``fill`` of the frame's diagonal.

    Parameters
    ----------
    board_size_mm : tuple of float
        Width and height of the board (its origin is the top-left corner), mm.
    camera_matrix : array_like
        3×3 intrinsics, px.
    image_size : tuple of int
        Frame width and height, px.
    count : int
        Number of poses.
    rng : numpy.random.Generator
        Draws angles and jitter.
    tilt_deg : tuple of float
        Range of the tilt, degrees.
    fill : float
        Board diagonal / frame diagonal.

    Returns
    -------
    list of (ndarray, ndarray)
        ``(rvec, tvec)`` board → camera (Rodrigues vector; mm).
    """
    import cv2
    import numpy as np

    kmat = np.asarray(camera_matrix, dtype=np.float64)
    w, h = image_size
    bw, bh = board_size_mm
    z = kmat[0, 0] * math.hypot(bw, bh) / (fill * math.hypot(w, h))
    spots = [(0.5, 0.5), (0.3, 0.3), (0.7, 0.3), (0.7, 0.7), (0.3, 0.7), (0.5, 0.3), (0.7, 0.5), (0.5, 0.7), (0.3, 0.5)]
    out = []
    for i in range(count):
        phi = 2 * math.pi * i / count + rng.uniform(-0.2, 0.2)
        alpha = math.radians(rng.uniform(*tilt_deg))
        gamma = math.radians(rng.uniform(-30, 30))
        tilt, _ = cv2.Rodrigues(np.array([math.cos(phi), math.sin(phi), 0.0]) * alpha)
        spin, _ = cv2.Rodrigues(np.array([0.0, 0.0, gamma]))
        rot = spin @ tilt
        u, v = spots[i % len(spots)]
        xn = (u * w - kmat[0, 2]) / kmat[0, 0]
        yn = (v * h - kmat[1, 2]) / kmat[1, 1]
        centre = z * np.array([xn, yn, 1.0])
        t = centre - rot @ np.array([bw / 2, bh / 2, 0.0])
        rvec, _ = cv2.Rodrigues(rot)
        out.append((rvec.ravel(), t))
    return out
