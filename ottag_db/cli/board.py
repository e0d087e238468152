"""The ``board`` commands: calibration boards (``board create``, ``board show``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ottag_db.cli.common import TAG_SIZE_HELP, Group, Progress, db_options, note, open_db, quiet_option

if TYPE_CHECKING:
    from ottag_db.app.boards import Board

__all__ = ["board_group"]


@click.group("board", cls=Group)
def board_group() -> None:
    """Calibration boards: a grid of distinct tags on one page and its .board.json."""


@board_group.command("create")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--rows", type=click.IntRange(min=1), required=True, help="Rows of tags.")
@click.option("--cols", type=click.IntRange(min=1), required=True, help="Columns of tags.")
@click.option("--tag-size", default="40mm", show_default=True, help=TAG_SIZE_HELP + ".")
@click.option("--spacing", default="10mm", show_default=True, help="White paper between neighbouring data areas.")
@click.option("--k", type=click.IntRange(3, 9), default=8, show_default=True, help="Point count of the default tags.")
@click.option("--dictionary", default=None, metavar="NAME", help="Take the tags from this dictionary (number order).")
@click.option("--page", default="A4", show_default=True, help="A4, A3, Letter, A4-landscape or WxH with a unit.")
@db_options
@quiet_option
def board_create(
    out: Path,
    rows: int,
    cols: int,
    tag_size: str,
    spacing: str,
    k: int,
    dictionary: str | None,
    page: str,
    db_target: str | None,
    quiet: bool,
) -> None:
    """Write a calibration board OUT.pdf (exact size, one page) and OUT.board.json beside it.

    Default tags: the highest-MP members of a flip-distance-2 set of k-point tags with
    unambiguous point labels. Board coordinates in the JSON are mm from the top-left corner of
    the first tag's data area, x right, y down.
    """
    from ottag_db.app.boards import create_board
    from ottag_db.app.export import FOUR_POINT_NOTE
    from ottag_db.errors import UsageError

    if k == 4 and dictionary is None:
        raise UsageError(f"--k 4: {FOUR_POINT_NOTE}")
    bar = Progress(f"flip graph of k = {k}", quiet)
    with open_db(db_target, quiet) as db:
        try:
            board, board_file = create_board(
                db,
                out,
                rows=rows,
                cols=cols,
                tag_size_mm=tag_size,
                spacing_mm=spacing,
                page=page,
                k=k,
                dictionary=dictionary,
                progress=bar,
            )
        finally:
            bar.close()
    w, h = board.size_mm
    click.echo(
        f"{out}: {rows} × {cols} board, {len(board.tags)} tags, tag size {board.tag_size_mm:g} mm, "
        f"spacing {board.spacing_mm:g} mm "
        f"(grid {w:g} × {h:g} mm); geometry in {board_file}"
    )
    note("print at 100 % scale and check the 100 mm ruler; mount the board flat", quiet)


@board_group.command("show")
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="The checked board file as JSON.")
def board_show(file: Path, as_json: bool) -> None:
    """Summarise (and check) a board file FILE.board.json."""
    from ottag_db.app.boards import read_board

    board = read_board(file)
    if as_json:
        click.echo(json.dumps(board.as_json()))
        return
    for line in _summary(board):
        click.echo(line)
    click.echo("row col  k  polarity  number  lambda")
    for t in board.tags:
        number = "-" if t.number is None else str(t.number)
        click.echo(f"{t.row:>3} {t.col:>3} {t.k:>2}  {t.polarity:<8}  {number:>6}  {t.lambda_text}")


def _summary(board: Board) -> list[str]:
    """Human-readable lines describing a board (``board show``).

    Parameters
    ----------
    board : Board
        The board.

    Returns
    -------
    list of str
        Grid, sizes, tags and correspondences per view.
    """
    w, h = board.size_mm
    ks = ", ".join(str(k) for k in board.ks)
    pols = sorted({t.polarity for t in board.tags})
    lines = [
        f"board: {board.rows} rows × {board.cols} columns, {len(board.tags)} tags (k = {ks}; {', '.join(pols)})",
        f"tag size {board.tag_size_mm:g} mm, spacing {board.spacing_mm:g} mm, "
        f"pitch {board.tag_size_mm + board.spacing_mm:g} mm, grid {w:g} × {h:g} mm",
        f"correspondences when the whole board is seen: {sum(t.k + 4 for t in board.tags)} "
        "(points + 4 corners per tag)",
    ]
    if board.dictionary:
        lines.append(f"tags from dictionary {board.dictionary}")
    if board.page_mm is not None:
        lines.append(f"page {board.page_mm[0]:g} × {board.page_mm[1]:g} mm")
    return lines
