"""Tag sheets and single-tag renders from the database (selection → geometry → PDF/PNG/SVG)."""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ottag_db.core import canonical
from ottag_db.core.types import POLARITIES, Polarity, ProgressCallback
from ottag_db.errors import ExportError, NotFoundError, UsageError
from ottag_db.printing.geometry import TagGeometry, build_tag_geometries
from ottag_db.printing.output import check_writable
from ottag_db.printing.raster import render_raster
from ottag_db.printing.sheet import SheetOptions, SheetReport, SheetTag, sheet_layout, write_tag_sheet
from ottag_db.printing.svg import render_svg
from ottag_db.store.db import Database
from ottag_db.store.dictionaries import dictionary_tag_records
from ottag_db.store.queries import find_order_type, missing_ks_note
from ottag_db.store.tags import TagRecord, select_tags

__all__ = [
    "FOUR_POINT_NOTE",
    "TagFilter",
    "check_sheet_name",
    "export_sheet",
    "render_tag",
    "resolve_tag",
    "select_for_export",
    "short_id",
    "tag_geometries",
]


#: Why no 4-point tag is ever drawn (README, "Tags and tag size").
FOUR_POINT_NOTE = (
    "order types of 4 points cannot be drawn as tags: the layout rules (every point a triangle vertex, "
    'triangles empty, disjoint, no shared edge; README "Tags and tag size") have no solution for 4 points '
    "- use k = 3 or 5 … 9"
)


def short_id(lambda_text: str) -> str:
    """Short printable form of an ID, stable wherever the database is built.

    Parameters
    ----------
    lambda_text : str
        Canonical ID in text form ``k:digits``.

    Returns
    -------
    str
        ``k-`` and the first 8 hex digits of the SHA-256 of ``lambda_text``.
    """
    k = lambda_text.split(":", 1)[0]
    return f"{k}-{hashlib.sha256(lambda_text.encode('ascii')).hexdigest()[:8]}"


@dataclass(frozen=True)
class TagFilter:
    """Which tags to take: point counts, MP ≥ ``min_mp`` (grid units), unique minimum, IDs."""

    ks: tuple[int, ...] = ()
    min_mp: float | None = None
    matchable: bool = False
    ids: tuple[str, ...] = ()

    def summary(self) -> str:
        """Human-readable description printed on every page."""
        parts = []
        if self.ks:
            parts.append("k = " + ", ".join(str(k) for k in self.ks))
        if self.min_mp is not None:
            parts.append(f"MP ≥ {self.min_mp:g} grid units")
        if self.matchable:
            parts.append("unique minimum only")
        if self.ids:
            parts.append(f"{len(self.ids)} chosen ID(s)")
        return "; ".join(parts) if parts else "all order types"


def _split_ids(ids: Sequence[str]) -> tuple[list[int], list[str]]:
    numbers: list[int] = []
    texts: list[str] = []
    for ident in ids:
        if ident.strip().isdigit():
            numbers.append(int(ident))
        else:
            texts.append(canonical.lambda_text(canonical.parse_lambda_text(ident)))
    return numbers, texts


def select_for_export(db: Database, flt: TagFilter) -> list[TagRecord]:
    """Tags matching ``flt`` (only reads the database).

    Parameters
    ----------
    db : Database
        An open database (may be read-only).
    flt : TagFilter
        Which tags; IDs may be given as database ids and as text IDs together.

    Returns
    -------
    list of TagRecord
        Ordered by k, then canonical λ.

    Raises
    ------
    ExportError
        Nothing matches.
    """
    numbers, texts = _split_ids(flt.ids)

    def pick(lambdas: Sequence[str], ids: Sequence[int]) -> list[TagRecord]:
        return select_tags(db, ks=flt.ks, min_mp=flt.min_mp, matchable=flt.matchable, lambdas=lambdas, ids=ids)

    if numbers and texts:
        # IDs given both ways: keep the tags matching either form.
        both = pick((), numbers) + pick(texts, ())
        tags = sorted({t.order_type_id: t for t in both}.values(), key=lambda t: (t.k, t.lambda_text))
    else:
        tags = pick(texts, numbers)
    if not tags:
        why = f"; {FOUR_POINT_NOTE}" if _asks_for_four_points(db, flt, numbers, texts) else ""
        why += missing_ks_note(db, flt.ks)
        raise ExportError(f"no tags match the filters ({flt.summary()}); nothing written{why}")
    return tags


def _asks_for_four_points(db: Database, flt: TagFilter, numbers: Sequence[int], texts: Sequence[str]) -> bool:
    """Whether the filter names 4-point order types (by ``--k`` or by ID), which have no tag."""
    if 4 in flt.ks or any(t.startswith("4:") for t in texts):
        return True
    if not numbers:
        return False
    with db.session() as s:
        return any((o := find_order_type(s, n)) is not None and o.k == 4 for n in numbers)


def tag_geometries(tags: Sequence[TagRecord], polarity: Polarity, tag_size: float) -> list[TagGeometry]:
    """Geometries of ``tags`` from their stored layouts and placements (nothing is recomputed).

    Parameters
    ----------
    tags : sequence of TagRecord
        Tags as read by :func:`ottag_db.store.tags.select_tags`.
    polarity : {"normal", "inverted"}
        Tones of every geometry.
    tag_size : float
        Data-area side, mm.

    Returns
    -------
    list of TagGeometry
        One per tag, in the order of ``tags``.
    """
    out: list[TagGeometry | None] = [None] * len(tags)
    for k in sorted({t.k for t in tags}):
        idx = [i for i, t in enumerate(tags) if t.k == k]
        pts = np.stack([tags[i].points for i in idx]).astype(np.float64)
        geoms = build_tag_geometries(
            pts,
            [tags[i].triangles for i in idx],
            polarity=polarity,
            tag_size=tag_size,
            placements=np.stack([tags[i].placement for i in idx]),
        )
        for i, g in zip(idx, geoms, strict=True):
            out[i] = g
    return [g for g in out if g is not None]


def check_sheet_name(path: Path) -> None:
    """Refuse a tag-sheet name that does not end in ``.pdf`` (a directory is left to
    :func:`~ottag_db.printing.output.check_writable`).

    Parameters
    ----------
    path : Path
        The output file asked for.

    Raises
    ------
    UsageError
        Another suffix; the message points to ``ottag-db render`` for one tag as PNG or SVG.
    """
    if not path.is_dir() and path.suffix.lower() != ".pdf":
        raise UsageError(
            f"{path}: export writes a PDF tag sheet, name it .pdf; for one tag as an image use "
            "ottag-db render ID OUT.png|OUT.svg"
        )


def export_sheet(
    db: Database,
    out: str | os.PathLike[str],
    flt: TagFilter,
    options: SheetOptions,
    *,
    polarity: str = "normal",
    dictionary: str | None = None,
    progress: ProgressCallback | None = None,
) -> SheetReport:
    """Write a PDF tag sheet of the selected tags (the database is only read).

    With ``both`` each tag is followed by its inverted variant. The filter summary and the
    polarity are printed on every page. A sheet of one polarity packs its tags (neighbours
    share quiet zones, see :mod:`ottag_db.printing.sheet_layout`); with ``both`` (and with
    cut marks) every tag keeps its whole quiet zone. ``SheetReport.per_page`` says how many
    tags a page holds. With ``dictionary`` the sheet holds that
    dictionary's members in number order (each in its own polarity, labelled with its tag
    number), narrowed by ``flt``.

    Parameters
    ----------
    db : Database
        An open database (may be read-only).
    out : str or PathLike
        The PDF file.
    flt : TagFilter
        Which tags.
    options : SheetOptions
        Sheet settings (its ``filter_summary`` is replaced by the filter's).
    polarity : {"normal", "inverted", "both"}
        Tones of the tags.
    dictionary : str, optional
        Print this dictionary's members instead.
    progress : ProgressCallback, optional
        ``progress(done, total)`` in pages: once with 0 before drawing, then after each page.

    Returns
    -------
    SheetReport
        What was written; ``seconds`` is the wall time of the whole call (selection,
        drawing and writing).

    Raises
    ------
    UsageError
        An output name not ending in ``.pdf`` (the message points to :func:`render_tag` /
        ``ottag-db render`` for single tags), bad polarity or sizes.
    ExportError
        Nothing matches (naming why 4-point order types never match), a tag does not fit, or
        the file cannot be written.
    """
    started = time.perf_counter()
    path = Path(out)
    check_sheet_name(path)
    if polarity not in ("normal", "inverted", "both"):
        raise UsageError(f"polarity must be normal, inverted or both, got {polarity!r}")
    check_writable(path)
    if dictionary is not None:
        rep = _export_dictionary_sheet(db, out, dictionary, flt, options, progress)
    else:
        rep = _export_filtered_sheet(db, out, flt, options, polarity, progress)
    return dataclasses.replace(rep, seconds=time.perf_counter() - started)


def _write_sheet(
    out: str | os.PathLike[str], tags: Sequence[SheetTag], options: SheetOptions, progress: ProgressCallback | None
) -> SheetReport:
    """:func:`write_tag_sheet` with ``progress(pages done, pages total)``, starting at 0."""
    if progress is None or not tags:
        return write_tag_sheet(out, tags, options)
    per_page = sheet_layout(options, tags).per_page
    pages = math.ceil(len(tags) / per_page)
    report_pages = progress
    report_pages(0, pages)

    def page_done(done: int, _total: int) -> None:
        report_pages(math.ceil(done / per_page), pages)

    return write_tag_sheet(out, tags, options, progress=page_done)


def _export_filtered_sheet(
    db: Database,
    out: str | os.PathLike[str],
    flt: TagFilter,
    options: SheetOptions,
    polarity: str,
    progress: ProgressCallback | None,
) -> SheetReport:
    tags = select_for_export(db, flt)
    polarities: list[Polarity] = list(POLARITIES) if polarity == "both" else [polarity]  # type: ignore[list-item]
    placed = tag_geometries(tags, polarities[0], options.tag_size_mm)  # place once, recolour below
    per_pol = {p: [g.with_polarity(p) for g in placed] for p in polarities}
    sheet_tags = [
        SheetTag(geom=per_pol[p][i], id_short=short_id(t.lambda_text), caption=f"#{t.order_type_id}")
        for i, t in enumerate(tags)
        for p in polarities
    ]
    summary = flt.summary() + f"; polarity {polarity}"
    opts = dataclasses.replace(options, filter_summary=summary)
    return _write_sheet(out, sheet_tags, opts, progress)


def _export_dictionary_sheet(
    db: Database,
    out: str | os.PathLike[str],
    name: str,
    flt: TagFilter,
    options: SheetOptions,
    progress: ProgressCallback | None,
) -> SheetReport:
    info, records = dictionary_tag_records(db, name)
    allowed = {t.order_type_id for t in select_tags(db, ks=flt.ks, min_mp=flt.min_mp, matchable=flt.matchable)}
    if flt.ids:
        allowed &= {t.order_type_id for t in select_for_export(db, TagFilter(ids=flt.ids))}
    chosen = [(m, t) for m, t in zip(info.members, records, strict=True) if m.order_type_id in allowed]
    if not chosen:
        raise ExportError(f"no tag of dictionary {name} matches the filters ({flt.summary()}); nothing written")
    members = [m for m, _ in chosen]
    ordered = [t for _, t in chosen]  # each member's own realization (the one the decoder verifies against)
    placed = tag_geometries(ordered, "normal", options.tag_size_mm)
    sheet_tags = [
        SheetTag(
            geom=g.with_polarity(m.polarity),  # type: ignore[arg-type]
            id_short=short_id(m.lambda_text),
            caption=f"{name} tag {m.number}",
        )
        for m, g in zip(members, placed, strict=True)
    ]
    summary = f"dictionary {name} (min flip distance {info.min_flip_distance}); " + flt.summary()
    return _write_sheet(out, sheet_tags, dataclasses.replace(options, filter_summary=summary), progress)


def resolve_tag(db: Database, ident: str) -> TagRecord:
    """The tag of one order type (only reads the database).

    Parameters
    ----------
    db : Database
        An open database (may be read-only).
    ident : str
        Text ID ``k:digits`` (any labeling) or database id.

    Returns
    -------
    TagRecord
        Its best realization with stored layout and placement.

    Raises
    ------
    NotFoundError
        Unknown ID, or a 4-point order type (the message says why it has no tag).
    """
    numbers, texts = _split_ids([ident])
    if any(t.startswith("4:") for t in texts):
        raise NotFoundError(f"no tag for {ident}: {FOUR_POINT_NOTE}")
    tags = select_tags(db, lambdas=texts, ids=numbers)
    if tags:
        return tags[0]
    with db.session() as s:
        found = find_order_type(s, numbers[0] if numbers else texts[0])
        if found is not None and found.k == 4:
            raise NotFoundError(f"no tag for {ident} (order type #{found.id}, k = 4): {FOUR_POINT_NOTE}")
        if found is not None:
            raise NotFoundError(f"order type {ident} has no stored layout; run ottag-db db upgrade")
    kind = "id" if numbers else "ID"
    raise NotFoundError(f"no order type with {kind} {ident} in the database (see ottag-db list)")


def render_tag(
    db: Database, ident: str, out: str | os.PathLike[str], *, px: int = 400, polarity: str = "normal"
) -> TagGeometry:
    """Render one tag to PNG (raster, data area ``px`` pixels wide) or SVG (mm, 50 mm tag).

    Parameters
    ----------
    db : Database
        An open database (may be read-only).
    ident : str
        Text ID or database id (see :func:`resolve_tag`).
    out : str or PathLike
        A ``.png`` or ``.svg`` file.
    px : int
        Data-area side in pixels of the PNG (≥ 16).
    polarity : {"normal", "inverted"}
        Tones of the tag.

    Returns
    -------
    TagGeometry
        The geometry drawn.

    Raises
    ------
    UsageError
        Another suffix, a bad polarity or ``px``.
    NotFoundError
        Unknown ID or k = 4.
    ExportError
        The file cannot be written.
    """
    path = Path(out)
    suffix = path.suffix.lower()
    if suffix not in (".png", ".svg"):
        raise UsageError(f"{path}: choose a .png or .svg output file")
    if polarity not in ("normal", "inverted"):
        raise UsageError(f"polarity must be normal or inverted, got {polarity!r}")
    if px < 16:
        raise UsageError(f"--px must be at least 16, got {px}")
    check_writable(path)
    tag = resolve_tag(db, ident)
    geom = tag_geometries([tag], polarity, 50.0)[0]  # type: ignore[arg-type]
    if suffix == ".svg":
        path.write_text(render_svg(geom, title=tag.lambda_text), encoding="utf-8")
    else:
        import cv2  # only PNG output needs OpenCV

        img = render_raster(geom, px)
        if not cv2.imwrite(str(path), img):
            raise ExportError(f"{path}: could not write the PNG")
    return geom
