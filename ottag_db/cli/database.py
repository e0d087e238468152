"""Commands on the order-type database: ``import``, ``stats``, ``show``, ``id``, ``list``, ``db``, ``sources``."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import click

from ottag_db.cli.common import CliUsageError, Group, Progress, db_options, note, open_db, quiet_option

if TYPE_CHECKING:
    from ottag_db.app.importing import ImportInterrupted, ImportJob
    from ottag_db.store.db import Database
    from ottag_db.store.importer import ImportReport
    from ottag_db.store.queries import OrderTypeSummary

__all__ = ["db_group", "id_cmd", "import_cmd", "list_cmd", "show_cmd", "sources_group", "stats_cmd"]


# ----------------------------------------------------------------------------- import
@click.command("import")
@click.argument("files", nargs=-1, type=click.Path(path_type=Path))
@click.option(
    "--points", "n", type=click.IntRange(3, 10), default=None, help="Points per record (else from the name otypesNN)."
)
@click.option(
    "--with-mirrors/--no-mirrors",
    default=None,
    help="Also store the mirror image of every chiral record [default: on for bundled data, off for files].",
)
@click.option(
    "--allow-duplicates",
    is_flag=True,
    help="Accept records of the same order type in one file (refused by default: usually a wrong --points).",
)
@click.option(
    "--k",
    "ks",
    type=click.IntRange(3, 10),
    multiple=True,
    help="Import the bundled file of these point counts (repeatable; 9 is not in the default import).",
)
@click.option(
    "--jobs",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    help="Processes that compute the tag layouts (e.g. 2 on two cores for --k 9); same result.",
)
@db_options
@quiet_option
def import_cmd(
    files: tuple[Path, ...],
    n: int | None,
    with_mirrors: bool | None,
    allow_duplicates: bool,
    ks: tuple[int, ...],
    jobs: int,
    db_target: str | None,
    quiet: bool,
) -> None:
    """Import point-set files (.b08/.b16) into the database; no FILE imports the bundled data.

    Without FILE: the bundled order types of 3 … 8 points; `--k 9` adds the 158,817
    nine-point ones (a few minutes on one core; use --jobs on several), `--k K` picks any bundled k. Each file is one
    transaction: a failure leaves the database as it was. Importing a file again is a no-op.
    Ctrl-C (or SIGTERM) rolls back the file being imported and says so.
    """
    from ottag_db.app.importing import ImportInterrupted, import_totals, interrupts_raise, plan_import
    from ottag_db.files.pointfile import inspect_point_file
    from ottag_db.store.importer import import_point_file

    plan = plan_import(files, n, with_mirrors, ks)
    for each in plan.jobs:  # names, sizes and formats first: a bad file list creates no database
        inspect_point_file(each.path, each.points)
    with open_db(db_target, quiet, create=True) as db:
        reports: list[ImportReport] = []
        try:
            with interrupts_raise():
                for job in plan.jobs:
                    bar = Progress(f"importing {job.path.name}", quiet)
                    try:
                        r = import_point_file(
                            db,
                            job.path,
                            n=job.points,
                            with_mirrors=plan.with_mirrors,
                            progress=bar,
                            allow_duplicates=allow_duplicates,
                            jobs=jobs,
                        )
                    finally:
                        bar.close()
                    reports.append(r)
                    _echo_report(r)
        except ImportInterrupted as exc:
            _interrupted(db, list(plan.jobs), reports, exc)
        if len(reports) > 1:
            t = import_totals(reports)
            click.echo(
                f"total: {t.records} records read, {t.new_order_types} new order types, "
                f"{t.new_realizations} new realizations"
            )
        note(f"database: {db.path or db.url}", quiet)


def _echo_report(r: ImportReport) -> None:
    if r.skipped:
        click.echo(f"{r.path.name}: already imported (sha256 matches), nothing to do")
    else:
        click.echo(
            f"{r.path.name}: {r.records} records read, {r.new_order_types} new order types, "
            f"{r.new_realizations} new realizations ({r.seconds:.2f} s)"
        )


def _interrupted(db: Database, jobs: list[ImportJob], reports: list[ImportReport], exc: ImportInterrupted) -> NoReturn:
    """Say what an interrupted import left behind, from the database itself, and exit 128 + signal."""
    from ottag_db.store.importer import is_imported

    committed = [r.path.name for r in reports]
    done = {r.path for r in reports}
    pending = [j for j in jobs if j.path not in done]
    # The signal may land anywhere: inside a file's transaction, just after its commit (before
    # its report), or between two files. The database, not the loop's position, tells which.
    if pending and is_imported(db, pending[0].path):
        click.echo(f"interrupted ({exc}): {pending[0].path.name} was imported (committed) before the signal", err=True)
        committed.append(pending[0].path.name)
        pending = pending[1:]
    if pending:
        names = ", ".join(j.path.name for j in pending)
        click.echo(f"interrupted ({exc}): {names} not imported, the database is unchanged by them", err=True)
    else:
        click.echo(f"interrupted ({exc}) after the last file was imported (committed)", err=True)
    if committed:
        click.echo(f"files already committed: {', '.join(committed)}", err=True)
    sys.exit(exc.exit_code)


# ----------------------------------------------------------------------------- stats
@click.command("stats")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output (see README).")
@db_options
@quiet_option
def stats_cmd(as_json: bool, db_target: str | None, quiet: bool) -> None:
    """Order types per k (Table 2), unique minimum (Table 3) and MP ≥ v counts (Table 7).

    Counts are given as stored (both chiralities when mirrors were imported) and up to
    reflection (a chiral pair once, as in the paper), the latter beside the paper's numbers.
    """
    from ottag_db.app.reports import PAPER_TABLE7, stats_json
    from ottag_db.core.types import COMPLETE_COUNTS, COMPLETE_COUNTS_UP_TO_REFLECTION, MP_THRESHOLDS
    from ottag_db.store.queries import database_stats

    with open_db(db_target, quiet) as db:
        stats = database_stats(db)
    if as_json:
        click.echo(json.dumps(stats_json(stats), indent=2))
        return
    if not stats:
        note("the database holds no order types yet: run `ottag-db import`")
        return
    click.echo("k  order types  unique min (E^k)  chiral | up to reflection: order types  unique min")
    for s in stats:
        click.echo(
            f"{s.k:<2} {s.order_types:>11}  {s.unique_min:>16}  {s.chiral:>6} | "
            f"{s.up_to_reflection:>30}  {s.unique_min_up_to_reflection:>10}"
            + (
                ""
                if s.complete
                else f"  (not all: {COMPLETE_COUNTS.get(s.k, '?')} exist, "
                f"{COMPLETE_COUNTS_UP_TO_REFLECTION.get(s.k, '?')} up to reflection)"
            )
        )
    click.echo("")
    click.echo(
        "Order types up to reflection whose best realization has MP >= v (grid units), beside the paper's Table 7"
    )
    shown = [s for s in stats if s.k >= 5]
    header = "v    " + "".join(f"{'k=' + str(s.k):>8}" for s in shown)
    header += "".join(f"{'paper' + str(s.k):>8}" for s in shown if s.k in PAPER_TABLE7)
    click.echo(header)
    for i, v in enumerate(MP_THRESHOLDS):
        line = f"{v:<4.1f} " + "".join(f"{s.mp_at_least_up_to_reflection[v]:>8}" for s in shown)
        line += "".join(f"{PAPER_TABLE7[s.k][i]:>8}" for s in shown if s.k in PAPER_TABLE7)
        click.echo(line)


# ----------------------------------------------------------------------------- show
def _matrix_lines(mat: Any) -> list[str]:
    k = mat.shape[0]
    return [" ".join("-" if i == j else str(int(mat[i, j])) for j in range(k)) for i in range(k)]


@click.command("show")
@click.argument("ident")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output.")
@db_options
@quiet_option
def show_cmd(ident: str, as_json: bool, db_target: str | None, quiet: bool) -> None:
    """Show one order type by canonical ID (k:digits) or database id."""
    from ottag_db.app.reports import order_type_json
    from ottag_db.store.queries import get_order_type

    with open_db(db_target, quiet) as db:
        detail = get_order_type(db, ident)
    if as_json:
        click.echo(json.dumps(order_type_json(detail), indent=2))
        return
    s = detail.summary
    click.echo(f"id          {s.id}")
    click.echo(f"number      {s.number if s.number is not None else '(import every order type of k to number it)'}")
    click.echo(f"lambda      {s.lambda_text}")
    click.echo(f"k           {s.k}")
    click.echo(f"hull size   {s.hull_size}")
    matching = "yes (usable for point matching)" if s.unique_min else "no"
    click.echo(f"unique min  {matching} ({s.minimal_orderings} minimal ordering(s))")
    mirror = (
        "itself (achiral)"
        if not s.chiral
        else f"{s.mirror}" + (f" (id {detail.mirror_id})" if detail.mirror_id else " (not in the database)")
    )
    click.echo(f"mirror      {mirror}")
    click.echo(f"MP          {s.mp:.3f} grid units (best of {s.realizations} realization(s))")
    best = detail.realizations[0]
    origin = f"{best.source} record {best.record_index}{' mirrored' if best.mirrored else ''}"
    click.echo(f"points      {' '.join(f'{x},{y}' for x, y in best.points)}  [{origin}]")
    click.echo(f"labeling    {' '.join(str(v) for v in best.labeling)}  (file index of canonical label 0, 1, ...)")
    click.echo("λ-matrix")
    for line in _matrix_lines(detail.lambda_matrix):
        click.echo("  " + line)


# ----------------------------------------------------------------------------- id
def _points_text(points: tuple[str, ...], points_opt: str | None, file: str | None) -> str:
    given = [bool(points), points_opt is not None, file is not None]
    if sum(given) != 1:
        raise CliUsageError(
            'give the points once: as arguments "x,y x,y ...", with --points TEXT or --file F (- = stdin)'
        )
    if points_opt is not None:
        return points_opt
    if file is not None or points == ("-",):
        source = file or "-"
        if source == "-":
            return sys.stdin.read()
        try:
            return Path(source).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise click.ClickException(f"{source}: cannot read the points ({exc})") from exc
    return " ".join(points)


@click.command("id", context_settings={"ignore_unknown_options": True})
@click.argument("points", nargs=-1)
@click.option("--points", "points_opt", metavar="TEXT", default=None, help='The points "x,y x,y ..." as an option.')
@click.option("--file", "points_file", metavar="F", default=None, help="Read the points from a file (- for stdin).")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output (see README).")
@db_options
@quiet_option
def id_cmd(
    points: tuple[str, ...],
    points_opt: str | None,
    points_file: str | None,
    as_json: bool,
    db_target: str | None,
    quiet: bool,
) -> None:
    """Canonical ID of an ad-hoc point set "x,y x,y ..." and whether the database has it.

    The points come as arguments, from --points TEXT, from --file F, or from stdin (-);
    negative coordinates need no "--". Without --db and no ./ottag.sqlite the ID is
    computed without a database lookup.
    """
    from ottag_db.store.db import resolve_database_url
    from ottag_db.store.queries import identify_points, parse_points

    pts = parse_points(_points_text(points, points_opt, points_file))
    _url, path = resolve_database_url(db_target)
    if db_target is None and path is not None and not path.exists():
        note(f"no database at {path}: the ID is not looked up (`ottag-db import` creates one)", quiet)
        res = identify_points(None, pts)
    else:
        with open_db(db_target, quiet) as db:
            res = identify_points(db, pts)
    if as_json:
        click.echo(json.dumps(res.as_json()))
        return
    click.echo(f"lambda      {res.lambda_text}")
    click.echo(f"k           {res.k}")
    click.echo(f"unique min  {'yes' if res.unique_min else 'no'} ({res.minimal_orderings} minimal ordering(s))")
    click.echo(f"hull size   {res.hull_size}")
    mp = f"{res.mp:.3f}" if res.mp == 0 or 1e-3 <= res.mp < 1e9 else f"{res.mp:.4g}"
    click.echo(f"MP          {mp} (coordinate units)")
    click.echo(f"labeling    {' '.join(str(v) for v in res.labeling)}")
    click.echo(f"in database {'yes, id ' + str(res.id) if res.in_database else 'no'}")
    if res.number is not None:
        click.echo(f"number      {res.number}")


# ----------------------------------------------------------------------------- list
def _echo_table(rows: list[OrderTypeSummary]) -> None:
    click.echo(f"{'id':>6} {'number':>6} {'k':>2} {'MP':>7} {'hull':>4} {'uniq':>4} {'chir':>4}  lambda")
    for r in rows:
        num = "-" if r.number is None else str(r.number)
        click.echo(
            f"{r.id:>6} {num:>6} {r.k:>2} {r.mp:>7.3f} {r.hull_size:>4} {'yes' if r.unique_min else 'no':>4} "
            f"{'yes' if r.chiral else 'no':>4}  {r.lambda_text}"
        )


@click.command("list")
@click.option("--k", "ks", type=click.IntRange(3, 10), multiple=True, help="Only these point counts (repeatable).")
@click.option("--min-mp", type=click.FloatRange(min=0), default=None, help="Only MP >= V (grid units, as Table 7).")
@click.option("--matchable", is_flag=True, help="Only order types with a unique minimal ordering (E^k).")
@click.option("--format", "fmt", type=click.Choice(["table", "csv", "json"]), default="table", show_default=True)
@db_options
@quiet_option
def list_cmd(
    ks: tuple[int, ...], min_mp: float | None, matchable: bool, fmt: str, db_target: str | None, quiet: bool
) -> None:
    """List order types with their best realization."""
    from ottag_db.app.reports import order_types_csv
    from ottag_db.store.queries import list_order_types

    with open_db(db_target, quiet) as db:
        rows = list_order_types(db, ks=ks, min_mp=min_mp, matchable=matchable)
    if fmt == "json":
        click.echo(json.dumps([r.as_json() for r in rows], indent=None))
    elif fmt == "csv":
        click.echo(order_types_csv(rows), nl=False)
    else:
        _echo_table(rows)
    note(f"{len(rows)} order type(s)", quiet)


# ----------------------------------------------------------------------------- db
@click.group("db", cls=Group)
def db_group() -> None:
    """Schema migrations (applied automatically whenever a command opens a database)."""


@db_group.command("current")
@db_options
def db_current(db_target: str | None) -> None:
    """Print the database's schema revision and the newest one this tool knows."""
    from ottag_db.store.db import head_revision, open_database

    db = open_database(db_target, migrate=False)
    try:
        cur = db.current_revision()
    finally:
        db.close()
    click.echo(f"current: {cur or '(empty)'}")
    click.echo(f"head:    {head_revision()}")


@db_group.command("upgrade")
@db_options
@quiet_option
def db_upgrade(db_target: str | None, quiet: bool) -> None:
    """Migrate the database to the newest schema (backing up an older file first)."""
    with open_db(db_target, quiet, create=True) as db:
        click.echo(f"at revision {db.current_revision()}")


@db_group.command("check")
@db_options
@quiet_option
def db_check(db_target: str | None, quiet: bool) -> None:
    """Run SQLite's integrity and foreign-key checks; exit 1 when the database is damaged."""
    from ottag_db.errors import DatabaseError
    from ottag_db.store.db import as_database_error, check_integrity, is_database_failure, open_database

    db = open_database(db_target, migrate=False, create=False)
    try:
        problems = check_integrity(db)
    except Exception as exc:
        if is_database_failure(exc):
            raise as_database_error(exc, db.path or db.url) from exc
        raise
    finally:
        db.close()
    if problems:
        for line in problems[:20]:
            click.echo(line)
        raise DatabaseError(
            f"{db.path}: integrity check failed ({len(problems)} problem(s)); restore a backup or rebuild "
            "it with `ottag-db import --db NEW_FILE`"
        )
    click.echo(f"{db.path}: ok")


# ----------------------------------------------------------------------------- sources
@click.group("sources", cls=Group, invoke_without_command=True)
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output: a JSON array.")
@db_options
@quiet_option
@click.pass_context
def sources_group(ctx: click.Context, as_json: bool, db_target: str | None, quiet: bool) -> None:
    """List the imported sources (point files); `sources remove NAME|ID` removes one."""
    if ctx.invoked_subcommand is not None:
        return
    from ottag_db.store.sources import list_sources

    with open_db(db_target, quiet) as db:
        rows = list_sources(db)
    if as_json:
        click.echo(json.dumps([r.as_json() for r in rows]))
        return
    click.echo(f"{'id':>4} {'n':>2} {'records':>8} {'realiz.':>8} {'types':>6} {'mirrors':>7}  {'imported':<19}  name")
    for r in rows:
        click.echo(
            f"{r.id:>4} {r.n:>2} {r.records:>8} {r.realizations:>8} {r.order_types:>6} "
            f"{'yes' if r.mirrors_included else 'no':>7}  {r.imported_at:%Y-%m-%d %H:%M:%S}  {r.name}"
        )
    note(f"{len(rows)} source(s)", quiet)


@sources_group.command("remove")
@click.argument("source")
@db_options
@quiet_option
def sources_remove(source: str, db_target: str | None, quiet: bool) -> None:
    """Remove one source (by name or id) with its realizations and the order types only it had."""
    from ottag_db.store.sources import remove_source

    with open_db(db_target, quiet) as db:
        removed = remove_source(db, source)
    click.echo(
        f"removed {removed.source.name} (id {removed.source.id}): {removed.realizations} realizations, "
        f"{removed.order_types} order types"
    )
