"""Tag sheets and single-tag renders from the database (selection → geometry → PDF/PNG/SVG)."""

from __future__ import annotations

import dataclasses
import hashlib
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ottag_db.core.canonical import lambda_text, parse_lambda_text
from ottag_db.core.types import Polarity, ProgressCallback
from ottag_db.errors import ExportError, NotFoundError, UsageError
from ottag_db.printing.render import TagGeometry, build_tag_geometries, render_raster, render_svg
from ottag_db.printing.sheet import SheetOptions, SheetReport, SheetTag, write_tag_sheet
from ottag_db.store.db import Database
from ottag_db.store.tags import TagRecord, select_tags

__all__ = ["TagFilter", "export_sheet", "render_tag", "resolve_tag", "short_id", "tag_geometries"]


def short_id(lambda_txt: str) -> str:
    """Short printable form of an ID: ``k-`` and the first 8 hex digits of SHA-256 of the text ID.

    Stable wherever the database is built (it depends on the canonical λ only).
    """
    k = lambda_txt.split(":", 1)[0]
    return f"{k}-{hashlib.sha256(lambda_txt.encode('ascii')).hexdigest()[:8]}"


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
            texts.append(lambda_text(parse_lambda_text(ident)))
    return numbers, texts


def select_for_export(db: Database, flt: TagFilter) -> list[TagRecord]:
    """Tags matching ``flt``; raises :class:`ExportError` when nothing matches."""
    numbers, texts = _split_ids(flt.ids)
    common = {"ks": flt.ks, "min_mp": flt.min_mp, "matchable": flt.matchable}
    if numbers and texts:
        # IDs given both ways: keep the tags matching either form.
        both = select_tags(db, ids=numbers, **common) + select_tags(db, lambdas=texts, **common)  # type: ignore[arg-type]
        tags = sorted({t.order_type_id: t for t in both}.values(), key=lambda t: (t.k, t.lambda_text))
    else:
        tags = select_tags(db, lambdas=texts, ids=numbers, **common)  # type: ignore[arg-type]
    if not tags:
        raise ExportError(f"no tags match the filters ({flt.summary()}); nothing written")
    return tags


def tag_geometries(tags: Sequence[TagRecord], polarity: Polarity, tag_size: float) -> list[TagGeometry]:
    """Geometries of ``tags`` in their order (batched by k)."""
    out: list[TagGeometry | None] = [None] * len(tags)
    for k in sorted({t.k for t in tags}):
        idx = [i for i, t in enumerate(tags) if t.k == k]
        pts = np.stack([tags[i].points for i in idx]).astype(np.float64)
        geoms = build_tag_geometries(pts, [tags[i].triangles for i in idx], polarity=polarity, tag_size=tag_size)
        for i, g in zip(idx, geoms, strict=True):
            out[i] = g
    return [g for g in out if g is not None]


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
    """Write a PDF tag sheet of the selected tags; ``polarity`` is normal, inverted or both.

    With ``both`` each tag is followed by its inverted variant. The filter summary and the
    polarity are printed on every page. With ``dictionary`` the sheet holds that
    dictionary's members in number order (each in its own polarity, labelled with its tag
    number), narrowed by ``flt``.
    """
    if polarity not in ("normal", "inverted", "both"):
        raise UsageError(f"polarity must be normal, inverted or both, got {polarity!r}")
    _check_writable(Path(out))
    if dictionary is not None:
        return _export_dictionary_sheet(db, out, dictionary, flt, options, progress)
    tags = select_for_export(db, flt)
    polarities: list[Polarity] = ["normal", "inverted"] if polarity == "both" else [polarity]  # type: ignore[list-item]
    placed = tag_geometries(tags, polarities[0], options.tag_size_mm)  # place once, recolour below
    per_pol = {p: [g.with_polarity(p) for g in placed] for p in polarities}
    sheet_tags = [
        SheetTag(geom=per_pol[p][i], id_short=short_id(t.lambda_text), caption=f"#{t.order_type_id}")
        for i, t in enumerate(tags)
        for p in polarities
    ]
    summary = flt.summary() + f"; polarity {polarity}"
    opts = dataclasses.replace(options, filter_summary=summary)
    return write_tag_sheet(out, sheet_tags, opts, progress=progress)


def _export_dictionary_sheet(
    db: Database,
    out: str | os.PathLike[str],
    name: str,
    flt: TagFilter,
    options: SheetOptions,
    progress: ProgressCallback | None,
) -> SheetReport:
    from ottag_db.store.dictionaries import get_dictionary

    info = get_dictionary(db, name)
    allowed = {t.order_type_id for t in select_tags(db, ks=flt.ks, min_mp=flt.min_mp, matchable=flt.matchable)}
    if flt.ids:
        allowed &= {t.order_type_id for t in select_for_export(db, TagFilter(ids=flt.ids))}
    members = [m for m in info.members if m.order_type_id in allowed]
    if not members:
        raise ExportError(f"no tag of dictionary {name} matches the filters ({flt.summary()}); nothing written")
    tags = {t.order_type_id: t for t in select_tags(db, ids=sorted({m.order_type_id for m in members}))}
    ordered = [tags[m.order_type_id] for m in members]
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
    return write_tag_sheet(out, sheet_tags, dataclasses.replace(options, filter_summary=summary), progress=progress)


def _check_writable(path: Path) -> None:
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ExportError(f"{path}: is a directory; give a file name")
    if not parent.exists():
        raise ExportError(f"{path}: the folder {parent} does not exist")
    if not os.access(parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise ExportError(f"{path}: cannot write there (permission denied)")


def resolve_tag(db: Database, ident: str) -> TagRecord:
    """The tag of one order type given by text ID or database id."""
    numbers, texts = _split_ids([ident])
    tags = select_tags(db, lambdas=texts, ids=numbers)
    if not tags:
        raise NotFoundError(f"no drawable tag for {ident} in the database (unknown ID, or k = 4)")
    return tags[0]


def render_tag(
    db: Database, ident: str, out: str | os.PathLike[str], *, px: int = 400, polarity: str = "normal"
) -> TagGeometry:
    """Render one tag to PNG (raster, data area ``px`` pixels wide) or SVG (mm, 50 mm tag)."""
    path = Path(out)
    suffix = path.suffix.lower()
    if suffix not in (".png", ".svg"):
        raise UsageError(f"{path}: choose a .png or .svg output file")
    if polarity not in ("normal", "inverted"):
        raise UsageError(f"polarity must be normal or inverted, got {polarity!r}")
    if px < 16:
        raise UsageError(f"--px must be at least 16, got {px}")
    _check_writable(path)
    tag = resolve_tag(db, ident)
    geom = tag_geometries([tag], polarity, 50.0)[0]  # type: ignore[arg-type]
    if suffix == ".svg":
        path.write_text(render_svg(geom, title=tag.lambda_text), encoding="utf-8")
    else:
        img = render_raster(geom, px)
        if not cv2.imwrite(str(path), img):
            raise ExportError(f"{path}: could not write the PNG")
    return geom
