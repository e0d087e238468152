"""SVG drawing of a tag: a standalone document in millimetres."""

from __future__ import annotations

from xml.sax.saxutils import escape

from ottag_db.printing.geometry import TagGeometry

__all__ = ["render_svg"]


def _f(v: float) -> str:
    text = f"{v:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def render_svg(geom: TagGeometry, *, title: str | None = None) -> str:
    """Standalone SVG document of the whole tag; user units are mm (``viewBox`` in mm).

    y grows downwards as in the unit coordinates, so points are not flipped. Triangles are
    one ``<path>``.

    Parameters
    ----------
    geom : TagGeometry
        The tag; ``tag_size`` and ``quiet_zone`` are taken as mm.
    title : str, optional
        Becomes the SVG ``<title>`` (escaped).

    Returns
    -------
    str
        The SVG document text.
    """
    t = geom.total_size
    q = geom.quiet_zone
    s = geom.tag_size
    quiet, data, tri = (("#000000" if v == 0 else "#ffffff") for v in geom.tones())
    pts = geom.points_array
    d = " ".join(
        "M{} {} L{} {} L{} {} Z".format(*(_f(q + s * c) for i in tri_idx for c in pts[i])) for tri_idx in geom.triangles
    )
    parts = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{_f(t)}mm" height="{_f(t)}mm" '
        f'viewBox="0 0 {_f(t)} {_f(t)}">',
    ]
    if title:
        parts.append(f"<title>{escape(title)}</title>")
    parts += [
        f'<rect x="0" y="0" width="{_f(t)}" height="{_f(t)}" fill="{quiet}"/>',
        f'<rect x="{_f(q)}" y="{_f(q)}" width="{_f(s)}" height="{_f(s)}" fill="{data}"/>',
        f'<path d="{d}" fill="{tri}" stroke="none"/>',
        "</svg>",
        "",
    ]
    return "\n".join(parts)
