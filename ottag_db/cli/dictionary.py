"""The ``dictionary`` commands: named tag dictionaries (create, list, show, delete, export, import)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ottag_db.cli.common import Group, Progress, db_options, note, open_db, quiet_option

__all__ = ["dictionary_group"]


@click.group("dictionary", cls=Group)
def dictionary_group() -> None:
    """Named tag dictionaries with stable numbers and a minimum flip distance."""


@dictionary_group.command("create")
@click.argument("name")
@click.option("--k", "ks", type=click.IntRange(3, 9), multiple=True, help="Only these point counts (repeatable).")
@click.option("--min-mp", type=click.FloatRange(min=0), default=None, help="Only MP >= V (grid units).")
@click.option("--matchable", is_flag=True, help="Only unique-minimum order types.")
@click.option("--polarity", type=click.Choice(["normal", "inverted", "both"]), default="normal", show_default=True)
@click.option("--include-mirrors/--no-mirrors", default=True, show_default=True, help="Both chiralities as members.")
@click.option(
    "--min-flip-distance",
    type=click.IntRange(1, 4),
    default=2,
    show_default=True,
    help="2: no two members are one triple-flip apart, so a single-triple misread is rejected.",
)
@click.option("--max-size", type=click.IntRange(min=1), default=None, help="At most N tags.")
@db_options
@quiet_option
def dictionary_create(
    name: str,
    ks: tuple[int, ...],
    min_mp: float | None,
    matchable: bool,
    polarity: str,
    include_mirrors: bool,
    min_flip_distance: int,
    max_size: int | None,
    db_target: str | None,
    quiet: bool,
) -> None:
    """Create dictionary NAME: greedy by MP (highest first), then k and λ; tags numbered 0 … N−1."""
    from ottag_db.core.types import COMPLETE_COUNTS
    from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary

    opts = DictionaryOptions(
        ks=ks,
        min_mp=min_mp,
        matchable=matchable,
        polarity=polarity,
        include_mirrors=include_mirrors,
        min_flip_distance=min_flip_distance,
        max_size=max_size,
    )
    with open_db(db_target, quiet) as db:
        bar = Progress("flip graph", quiet)
        try:
            info = create_dictionary(db, name, opts, progress=bar)
        finally:
            bar.close()
    click.echo(f"dictionary {info.name}: {len(info.members)} tags, min flip distance {info.min_flip_distance}")
    for k, n in info.counts().items():
        click.echo(f"  k = {k}: {n} tags (of {COMPLETE_COUNTS.get(k, '?')} order types)")


@dictionary_group.command("list")
@db_options
@quiet_option
def dictionary_list(db_target: str | None, quiet: bool) -> None:
    """List dictionaries."""
    from ottag_db.store.dictionaries import list_dictionaries

    with open_db(db_target, quiet) as db:
        rows = list_dictionaries(db)
    for name, dist, n, created in rows:
        click.echo(f"{name}\t{n} tags\tmin flip distance {dist}\tcreated {created:%Y-%m-%d %H:%M}")
    note(f"{len(rows)} dictionar{'y' if len(rows) == 1 else 'ies'}", quiet)


@dictionary_group.command("show")
@click.argument("name")
@db_options
@quiet_option
def dictionary_show(name: str, db_target: str | None, quiet: bool) -> None:
    """Show a dictionary's members."""
    from ottag_db.store.dictionaries import get_dictionary

    with open_db(db_target, quiet) as db:
        info = get_dictionary(db, name)
    click.echo(f"{info.name}: {len(info.members)} tags, min flip distance {info.min_flip_distance}")
    click.echo(f"parameters: {json.dumps(info.parameters, sort_keys=True)}")
    click.echo(f"{'tag':>5} {'number':>6} {'k':>2} {'MP':>7} {'polarity':>8}  lambda")
    for m in info.members:
        num = "-" if m.universal_number is None else str(m.universal_number)
        click.echo(f"{m.number:>5} {num:>6} {m.k:>2} {m.mp:>7.3f} {m.polarity:>8}  {m.lambda_text}")


@dictionary_group.command("delete")
@click.argument("name")
@db_options
@quiet_option
def dictionary_delete(name: str, db_target: str | None, quiet: bool) -> None:
    """Delete a dictionary."""
    from ottag_db.store.dictionaries import delete_dictionary

    with open_db(db_target, quiet) as db:
        n = delete_dictionary(db, name)
    click.echo(f"deleted dictionary {name} ({n} tags)")


@dictionary_group.command("export")
@click.argument("name")
@click.option("--format", "fmt", type=click.Choice(["json", "csv"]), default="json", show_default=True)
@click.option("--output", "-o", type=click.Path(path_type=Path), default=None, help="File to write [default: stdout].")
@db_options
@quiet_option
def dictionary_export(name: str, fmt: str, output: Path | None, db_target: str | None, quiet: bool) -> None:
    """Export a dictionary (everything another implementation needs) as JSON or CSV."""
    from ottag_db.app.dictionary_io import write_dictionary_file
    from ottag_db.store.dictionary_files import export_dictionary

    with open_db(db_target, quiet) as db:
        text = export_dictionary(db, name, fmt)
    if output is None:
        click.echo(text, nl=not text.endswith("\n"))
    else:
        write_dictionary_file(output, text)
        note(f"wrote {output}", quiet)


@dictionary_group.command("import")
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--name", default=None, help="Store under this name instead of the file's.")
@db_options
@quiet_option
def dictionary_import(file: Path, name: str | None, db_target: str | None, quiet: bool) -> None:
    """Import a dictionary from its JSON export, with its geometry (its order types must be in the database).

    Every tag is checked (points in general position whose order type is its lambda, triangles
    obeying the layout rules); a bad tag stops the import with one line naming it and nothing is
    stored. The file's points and triangles become the tags this database prints and verifies.
    """
    from ottag_db.app.dictionary_io import read_dictionary_file
    from ottag_db.store.dictionary_files import import_dictionary

    text = read_dictionary_file(file)
    with open_db(db_target, quiet) as db:
        info = import_dictionary(db, text, source=str(file), name=name)
    click.echo(f"imported dictionary {info.name}: {len(info.members)} tags")
