"""The ``ottag-db`` command line: parses options, calls the library, prints results.

One module per command group; each command imports the library inside its body, so
``ottag-db --version`` and ``--help`` load click and nothing heavy (no numpy, OpenCV, SciPy,
reportlab, SQLAlchemy or Alembic).
"""

from __future__ import annotations

import click

import ottag_db
from ottag_db.cli.board import board_group
from ottag_db.cli.calibrate import calibrate_cmd
from ottag_db.cli.common import Group, root_options
from ottag_db.cli.database import db_group, id_cmd, import_cmd, list_cmd, show_cmd, sources_group, stats_cmd
from ottag_db.cli.decode import decode_cmd
from ottag_db.cli.dictionary import dictionary_group
from ottag_db.cli.generate import generate_cmd
from ottag_db.cli.tags import export_cmd, render_cmd

__all__ = ["cli", "main"]


@click.group(cls=Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(ottag_db.__version__, prog_name="ottag-db")
@root_options
def cli(db_target: str | None, quiet: bool) -> None:
    """Order Type Tags: order-type database, tag sheets and decoder.

    IDs are printed in the text form k:digits (the canonical λ-matrix, row-major,
    diagonal 0). Data goes to stdout, messages and progress to stderr.
    """


for _command in (
    import_cmd,
    stats_cmd,
    show_cmd,
    id_cmd,
    list_cmd,
    generate_cmd,
    export_cmd,
    render_cmd,
    decode_cmd,
    board_group,
    calibrate_cmd,
    dictionary_group,
    db_group,
    sources_group,
):
    cli.add_command(_command)


def main() -> None:
    """Console-script entry point: run the command line on ``sys.argv`` and exit."""
    cli(prog_name="ottag-db")
