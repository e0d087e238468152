"""Commands that draw tags: ``export`` (a PDF sheet) and ``render`` (one tag as PNG or SVG)."""

from __future__ import annotations

import time
from pathlib import Path

import click

from ottag_db.cli.common import TAG_SIZE_HELP, Progress, db_options, note, open_db, quiet_option

__all__ = ["export_cmd", "render_cmd"]


@click.command("export")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--k", "ks", type=click.IntRange(3, 9), multiple=True, help="Only these point counts (repeatable).")
@click.option("--min-mp", type=click.FloatRange(min=0), default=None, help="Only MP >= V (grid units, as Table 7).")
@click.option("--matchable", is_flag=True, help="Only unique-minimum order types (point matching).")
@click.option("--ids", "ids", multiple=True, metavar="ID", help="Only these IDs (k:digits or database id; repeatable).")
@click.option(
    "--dictionary", default=None, metavar="NAME", help="Only this dictionary's tags, labelled with their numbers."
)
@click.option("--polarity", type=click.Choice(["normal", "inverted", "both"]), default="normal", show_default=True)
@click.option("--tag-size", default="50mm", show_default=True, help=TAG_SIZE_HELP + ".")
@click.option("--quiet-zone", default=None, help="White border around the data area [default: 0.25 × tag size].")
@click.option("--page", default="A4", show_default=True, help="A4, Letter, or WxH with a unit (e.g. 210x297mm).")
@click.option("--margin", default="10mm", show_default=True, help="Page margin.")
@click.option("--spacing", default="0mm", show_default=True, help="Extra paper between tags, beyond their quiet zones.")
@click.option(
    "--pack/--no-pack",
    default=True,
    show_default=True,
    help="Tags of one polarity share their quiet zones (off with --cut-marks).",
)
@click.option(
    "--labels/--no-labels", default=True, show_default=True, help="Label under each tag, outside the quiet zones."
)
@click.option(
    "--cut-marks/--no-cut-marks",
    default=False,
    show_default=True,
    help="Corner marks for cutting; every tag keeps its whole quiet zone.",
)
@db_options
@quiet_option
def export_cmd(
    out: Path,
    ks: tuple[int, ...],
    min_mp: float | None,
    matchable: bool,
    ids: tuple[str, ...],
    dictionary: str | None,
    polarity: str,
    tag_size: str,
    quiet_zone: str | None,
    page: str,
    margin: str,
    spacing: str,
    pack: bool,
    labels: bool,
    cut_marks: bool,
    db_target: str | None,
    quiet: bool,
) -> None:
    """Write a print-ready vector PDF tag sheet OUT.pdf in exact physical size.

    Tag size is the side of the black data area. As many tags as fit go on a page: tags of
    one polarity share their quiet zones, labels sit outside every quiet zone. Print at
    100 % scale and check the 100 mm ruler on every page. For one tag as PNG or SVG use
    ``ottag-db render``.
    """
    started = time.perf_counter()  # the report gives the wall time of the whole command
    from ottag_db.app.export import FOUR_POINT_NOTE, TagFilter, check_sheet_name, export_sheet

    check_sheet_name(out)  # before the database is opened
    from ottag_db.app.options import sheet_options

    options = sheet_options(
        tag_size=tag_size,
        quiet_zone=quiet_zone,
        page=page,
        margin=margin,
        spacing=spacing,
        labels=labels,
        cut_marks=cut_marks,
        pack=pack,
    )
    flt = TagFilter(ks=ks, min_mp=min_mp, matchable=matchable, ids=ids)
    with open_db(db_target, quiet) as db:
        bar = Progress("drawing pages", quiet, show_pos=True)
        try:
            rep = export_sheet(db, out, flt, options, polarity=polarity, dictionary=dictionary, progress=bar)
        finally:
            bar.close()
    if 4 in ks:
        note(f"note: k = 4 skipped: {FOUR_POINT_NOTE}", quiet)
    shared = ", shared quiet zones" if rep.packed else ""
    click.echo(
        f"{out}: {rep.tags} tags on {rep.pages} page(s), {rep.per_page} per page ({rep.columns}×{rep.rows}{shared}), "
        f"tag size {rep.tag_size_mm:g} mm (quiet zone {rep.quiet_zone_mm:g} mm), "
        f"{time.perf_counter() - started:.1f} s"
    )


@click.command("render")
@click.argument("ident")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--px", type=int, default=400, show_default=True, help="PNG: data-area width in pixels.")
@click.option("--polarity", type=click.Choice(["normal", "inverted"]), default="normal", show_default=True)
@db_options
@quiet_option
def render_cmd(ident: str, out: Path, px: int, polarity: str, db_target: str | None, quiet: bool) -> None:
    """Render one tag (ID as k:digits or database id) to OUT.png or OUT.svg.

    SVG is in mm with a 50 mm data area (the side of the black square).
    """
    from ottag_db.app.export import render_tag

    with open_db(db_target, quiet) as db:
        geom = render_tag(db, ident, out, px=px, polarity=polarity)
    click.echo(f"{out}: k = {geom.k}, {polarity}, printed MP {geom.mp_unit:.4f} × tag size")
