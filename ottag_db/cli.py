"""The ``ottag-db`` command line: parses options, calls the library, prints results."""

from __future__ import annotations

import csv
import io
import json
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import click

from ottag_db import __version__
from ottag_db.errors import OttagError
from ottag_db.store.db import Database, head_revision, open_database
from ottag_db.store.importer import ImportReport, import_point_file
from ottag_db.store.queries import (
    MP_THRESHOLDS,
    KStats,
    OrderTypeSummary,
    database_stats,
    get_order_type,
    identify_points,
    list_order_types,
    parse_points,
)

__all__ = ["cli", "main"]

F = TypeVar("F", bound=Callable[..., Any])

#: Paper's Table 7 (|D^k| for v = 0.5 … 9.0), printed beside our counts.
PAPER_TABLE7: dict[int, tuple[int, ...]] = {
    8: (3315, 3296, 1240, 642, 371, 231, 135, 83, 56, 37, 26, 15, 10, 6, 5, 4, 3, 3),
    7: (135, 135, 135, 135, 135, 86, 60, 47, 32, 26, 18, 15, 8, 7, 4, 3, 3, 3),
    6: (16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 12, 10, 8, 6, 5),
    5: (3,) * 18,
}


class _CliError(click.ClickException):
    """A library error shown as ``error: message`` on stderr, exit code 1."""

    def show(self, file: Any = None) -> None:
        click.echo(f"error: {self.format_message()}", err=True)


class _CliUsageError(_CliError):
    """A bad option value caught by the library: exit code 2 like click's own usage errors."""

    exit_code = 2


class _Group(click.Group):
    """Turns the library's typed errors into one-line messages with the right exit code."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except OttagError as exc:
            if exc.exit_code == 2:
                raise _CliUsageError(str(exc)) from exc
            raise _CliError(str(exc)) from exc


def _db_options(func: F) -> F:
    func = click.option(
        "--db",
        "db_target",
        envvar="OTTAG_DB",
        default=None,
        metavar="PATH|URL",
        help="Database file or SQLAlchemy URL [env OTTAG_DB; default ./ottag.sqlite].",
    )(func)
    return func


def _quiet_option(func: F) -> F:
    return click.option("--quiet", "-q", is_flag=True, help="No progress bars or notes on stderr.")(func)


def _note(msg: str, quiet: bool = False) -> None:
    if not quiet:
        click.echo(msg, err=True)


@contextmanager
def _database(target: str | None, quiet: bool = False) -> Iterator[Database]:
    db = open_database(target)
    if db.backup is not None:
        _note(f"migrated {db.path} to revision {head_revision()} (backup: {db.backup})", quiet)
    try:
        yield db
    finally:
        db.close()


class _Progress:
    """A click progress bar on stderr driven by ``(done, total)`` callbacks."""

    def __init__(self, label: str, quiet: bool):
        self.label = label
        self.quiet = quiet
        self._bar: Any = None
        self._done = 0

    def __call__(self, done: int, total: int) -> None:
        if self.quiet:
            return
        if self._bar is None:
            self._bar = click.progressbar(length=total, label=self.label, file=sys.stderr)
            self._bar.__enter__()
        self._bar.update(done - self._done)
        self._done = done

    def close(self) -> None:
        if self._bar is not None:
            self._bar.__exit__(None, None, None)
            self._bar = None
            self._done = 0


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="ottag-db")
def cli() -> None:
    """Order Type Tags: order-type database, tag sheets and decoder.

    IDs are printed in the text form k:digits (the canonical λ-matrix, row-major,
    diagonal 0). Data goes to stdout, messages and progress to stderr.
    """


# ----------------------------------------------------------------------------- import
@cli.command("import")
@click.argument("files", nargs=-1, type=click.Path(path_type=Path))
@click.option(
    "--points", "n", type=click.IntRange(3, 10), default=None, help="Points per record (else from the name otypesNN)."
)
@click.option(
    "--with-mirrors/--no-mirrors",
    default=None,
    help="Also store the mirror image of every chiral record [default: on for bundled data, off for files].",
)
@_db_options
@_quiet_option
def import_cmd(
    files: tuple[Path, ...], n: int | None, with_mirrors: bool | None, db_target: str | None, quiet: bool
) -> None:
    """Import point-set files (.b08/.b16) into the database; no FILE imports the bundled data.

    Each file is one transaction: a failure leaves the database as it was. Importing a file
    again is a no-op.
    """
    from ottag_db.files.bundled import bundled_point_files

    jobs: list[tuple[Path, int | None]] = [(p, n) for p in files]
    mirrors = with_mirrors
    if not jobs:
        jobs = [(p, k) for p, k in bundled_point_files()]
        mirrors = True if with_mirrors is None else with_mirrors
    with _database(db_target, quiet) as db:
        reports: list[ImportReport] = []
        for p, points in jobs:
            bar = _Progress(f"importing {p.name}", quiet)
            try:
                reports.append(import_point_file(db, p, n=points, with_mirrors=bool(mirrors), progress=bar))
            finally:
                bar.close()
            r = reports[-1]
            if r.skipped:
                click.echo(f"{p.name}: already imported (sha256 matches), nothing to do")
            else:
                click.echo(
                    f"{p.name}: {r.records} records read, {r.new_order_types} new order types, "
                    f"{r.new_realizations} new realizations ({r.seconds:.2f} s)"
                )
        if len(reports) > 1:
            click.echo(
                f"total: {sum(r.records for r in reports)} records read, "
                f"{sum(r.new_order_types for r in reports)} new order types, "
                f"{sum(r.new_realizations for r in reports)} new realizations"
            )
        _note(f"database: {db.path or db.url}", quiet)


# ----------------------------------------------------------------------------- stats
def _stats_json(stats: list[KStats]) -> dict[str, Any]:
    return {
        str(s.k): {
            "order_types": s.order_types,
            "unique_min": s.unique_min,
            "chiral": s.chiral,
            "mp_at_least": {f"{v:.1f}": c for v, c in s.mp_at_least.items()},
            "up_to_reflection": {
                "order_types": s.up_to_reflection,
                "unique_min": s.unique_min_up_to_reflection,
                "mp_at_least": {f"{v:.1f}": c for v, c in s.mp_at_least_up_to_reflection.items()},
            },
        }
        for s in stats
    }


@cli.command("stats")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output (see README).")
@_db_options
@_quiet_option
def stats_cmd(as_json: bool, db_target: str | None, quiet: bool) -> None:
    """Order types per k (Table 2), unique minimum (Table 3) and MP ≥ v counts (Table 7).

    Counts are given as stored (both chiralities when mirrors were imported) and up to
    reflection (a chiral pair once, as in the paper), the latter beside the paper's numbers.
    """
    with _database(db_target, quiet) as db:
        stats = database_stats(db)
    if as_json:
        click.echo(json.dumps(_stats_json(stats), indent=2))
        return
    if not stats:
        _note("the database holds no order types yet: run `ottag-db import`")
        return
    click.echo("k  order types  unique min (E^k)  chiral | up to reflection: order types  unique min")
    for s in stats:
        click.echo(
            f"{s.k:<2} {s.order_types:>11}  {s.unique_min:>16}  {s.chiral:>6} | "
            f"{s.up_to_reflection:>30}  {s.unique_min_up_to_reflection:>10}"
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


@cli.command("show")
@click.argument("ident")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output.")
@_db_options
@_quiet_option
def show_cmd(ident: str, as_json: bool, db_target: str | None, quiet: bool) -> None:
    """Show one order type by canonical ID (k:digits) or database id."""
    with _database(db_target, quiet) as db:
        detail = get_order_type(db, ident)
    s = detail.summary
    if as_json:
        out = s.as_json()
        out["lambda_matrix"] = detail.lambda_matrix.tolist()
        out["mirror_id"] = detail.mirror_id
        out["all_realizations"] = [
            {
                "id": r.id,
                "source": r.source,
                "record": r.record_index,
                "mirrored": r.mirrored,
                "points": r.points,
                "mp": r.mp,
                "labeling": list(r.labeling),
            }
            for r in detail.realizations
        ]
        click.echo(json.dumps(out, indent=2))
        return
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
@cli.command("id")
@click.argument("points")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output (see README).")
@_db_options
@_quiet_option
def id_cmd(points: str, as_json: bool, db_target: str | None, quiet: bool) -> None:
    """Canonical ID of an ad-hoc point set "x,y x,y ..." and whether the database has it."""
    pts = parse_points(points)
    with _database(db_target, quiet) as db:
        res = identify_points(db, pts)
    if as_json:
        click.echo(json.dumps(res.as_json()))
        return
    click.echo(f"lambda      {res.lambda_text}")
    click.echo(f"k           {res.k}")
    click.echo(f"unique min  {'yes' if res.unique_min else 'no'} ({res.minimal_orderings} minimal ordering(s))")
    click.echo(f"hull size   {res.hull_size}")
    click.echo(f"MP          {res.mp:.3f}")
    click.echo(f"labeling    {' '.join(str(v) for v in res.labeling)}")
    click.echo(f"in database {'yes, id ' + str(res.id) if res.in_database else 'no'}")
    if res.number is not None:
        click.echo(f"number      {res.number}")


# ----------------------------------------------------------------------------- list
def _write_list(rows: list[OrderTypeSummary], fmt: str) -> None:
    if fmt == "json":
        click.echo(json.dumps([r.as_json() for r in rows], indent=None))
        return
    if fmt == "csv":
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["id", "k", "lambda", "mp", "points", "hull_size", "unique_min", "chiral", "mirror", "number"])
        for r in rows:
            pts = " ".join(f"{x},{y}" for x, y in r.points)
            w.writerow(
                [
                    r.id,
                    r.k,
                    r.lambda_text,
                    f"{r.mp:.6f}",
                    pts,
                    r.hull_size,
                    int(r.unique_min),
                    int(r.chiral),
                    r.mirror,
                    "" if r.number is None else r.number,
                ]
            )
        click.echo(buf.getvalue(), nl=False)
        return
    click.echo(f"{'id':>6} {'number':>6} {'k':>2} {'MP':>7} {'hull':>4} {'uniq':>4} {'chir':>4}  lambda")
    for r in rows:
        num = "-" if r.number is None else str(r.number)
        click.echo(
            f"{r.id:>6} {num:>6} {r.k:>2} {r.mp:>7.3f} {r.hull_size:>4} {'yes' if r.unique_min else 'no':>4} "
            f"{'yes' if r.chiral else 'no':>4}  {r.lambda_text}"
        )


@cli.command("list")
@click.option("--k", "ks", type=click.IntRange(3, 10), multiple=True, help="Only these point counts (repeatable).")
@click.option("--min-mp", type=click.FloatRange(min=0), default=None, help="Only MP >= V (grid units, as Table 7).")
@click.option("--matchable", is_flag=True, help="Only order types with a unique minimal ordering (E^k).")
@click.option("--format", "fmt", type=click.Choice(["table", "csv", "json"]), default="table", show_default=True)
@_db_options
@_quiet_option
def list_cmd(
    ks: tuple[int, ...], min_mp: float | None, matchable: bool, fmt: str, db_target: str | None, quiet: bool
) -> None:
    """List order types with their best realization."""
    with _database(db_target, quiet) as db:
        rows = list_order_types(db, ks=ks, min_mp=min_mp, matchable=matchable)
    _write_list(rows, fmt)
    _note(f"{len(rows)} order type(s)", quiet)


# ----------------------------------------------------------------------------- generate
class _StageProgress:
    """Progress bars for ``progress(stage, done, total)`` callbacks: one bar per stage."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.stage: str | None = None
        self.bar: _Progress | None = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage != self.stage:
            self.close()
            self.stage = stage
            self.bar = _Progress(stage, self.quiet)
        assert self.bar is not None
        self.bar(done, total)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


@cli.command("generate")
@click.option("--max-k", type=click.IntRange(3, 8), default=8, show_default=True, help="Largest number of points.")
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=Path("data"),
    show_default=True,
    help="Folder for ottag-kNN.b08 files and manifest.json.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Same seed, same files.")
@click.option("--jobs", type=click.IntRange(min=1), default=1, show_default=True, help="Worker processes.")
@_quiet_option
def generate_cmd(max_k: int, out_dir: Path, seed: int, jobs: int, quiet: bool) -> None:
    """Enumerate every order type of 3 … MAX_K points and realize each on the 8-bit grid with maximal MP.

    Writes one set per reflection pair (drop-in replacements of Aichholzer's otypesNN.b08)
    plus a manifest; `ottag-db import OUT/ottag-kNN.b08 --with-mirrors` loads them.
    """
    from ottag_db.generation.enumeration import generate_database

    bar = _StageProgress(quiet)
    try:
        rep = generate_database(max_k=max_k, out_dir=out_dir, seed=seed, jobs=jobs, progress=bar)
    finally:
        bar.close()
    for k in sorted(rep.records):
        click.echo(
            f"k = {k}: {rep.records[k]} order types up to reflection ({rep.with_mirrors[k]} with mirrors), "
            f"min MP {rep.mp_min[k]:.2f} -> {rep.files[k]}"
        )
    click.echo(f"manifest: {rep.manifest}")
    click.echo(
        f"time: {rep.seconds['total']:.0f} s (enumerate {rep.seconds['enumerate']:.0f} s, "
        f"realize {rep.seconds['realize']:.0f} s)"
    )


# ----------------------------------------------------------------------------- export / render
_TAG_SIZE_HELP = (
    "Side of the black data area (the square you measure with a ruler and give to the pose "
    "estimator), with a unit: mm, cm or in"
)


@cli.command("export")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--k", "ks", type=click.IntRange(3, 8), multiple=True, help="Only these point counts (repeatable).")
@click.option("--min-mp", type=click.FloatRange(min=0), default=None, help="Only MP >= V (grid units, as Table 7).")
@click.option("--matchable", is_flag=True, help="Only unique-minimum order types (point matching).")
@click.option("--ids", "ids", multiple=True, metavar="ID", help="Only these IDs (k:digits or database id; repeatable).")
@click.option(
    "--dictionary", default=None, metavar="NAME", help="Only this dictionary's tags, labelled with their numbers."
)
@click.option("--polarity", type=click.Choice(["normal", "inverted", "both"]), default="normal", show_default=True)
@click.option("--tag-size", default="50mm", show_default=True, help=_TAG_SIZE_HELP + ".")
@click.option("--quiet-zone", default=None, help="White border around the data area [default: 0.25 × tag size].")
@click.option("--page", default="A4", show_default=True, help="A4, Letter, or WxH with a unit (e.g. 210x297mm).")
@click.option("--margin", default="10mm", show_default=True, help="Page margin.")
@click.option("--spacing", default="5mm", show_default=True, help="Space between tags.")
@click.option("--labels/--no-labels", default=True, show_default=True, help="Label under each tag.")
@click.option("--cut-marks/--no-cut-marks", default=False, show_default=True, help="Corner marks for cutting.")
@_db_options
@_quiet_option
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
    labels: bool,
    cut_marks: bool,
    db_target: str | None,
    quiet: bool,
) -> None:
    """Write a print-ready vector PDF tag sheet OUT.pdf in exact physical size.

    Tag size is the side of the black data area. Print at 100 % scale and check the 100 mm
    ruler on every page.
    """
    from ottag_db.app.export import TagFilter, export_sheet
    from ottag_db.printing.sheet import SheetOptions, parse_length, parse_page

    options = SheetOptions(
        tag_size_mm=parse_length(tag_size),
        quiet_zone_mm=None if quiet_zone is None else parse_length(quiet_zone),
        page=parse_page(page),
        margin_mm=parse_length(margin),
        spacing_mm=parse_length(spacing),
        labels=labels,
        cut_marks=cut_marks,
    )
    flt = TagFilter(ks=ks, min_mp=min_mp, matchable=matchable, ids=ids)
    with _database(db_target, quiet) as db:
        bar = _Progress("writing tags", quiet)
        try:
            rep = export_sheet(db, out, flt, options, polarity=polarity, dictionary=dictionary, progress=bar)
        finally:
            bar.close()
    click.echo(
        f"{out}: {rep.tags} tags on {rep.pages} page(s), tag size {rep.tag_size_mm:g} mm "
        f"(quiet zone {rep.quiet_zone_mm:g} mm), {rep.columns}×{rep.rows} per page, {rep.seconds:.1f} s"
    )


@cli.command("render")
@click.argument("ident")
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--px", type=int, default=400, show_default=True, help="PNG: data-area width in pixels.")
@click.option("--polarity", type=click.Choice(["normal", "inverted"]), default="normal", show_default=True)
@_db_options
@_quiet_option
def render_cmd(ident: str, out: Path, px: int, polarity: str, db_target: str | None, quiet: bool) -> None:
    """Render one tag (ID as k:digits or database id) to OUT.png or OUT.svg.

    SVG is in mm with a 50 mm data area (the side of the black square).
    """
    from ottag_db.app.export import render_tag

    with _database(db_target, quiet) as db:
        geom = render_tag(db, ident, out, px=px, polarity=polarity)
    click.echo(f"{out}: k = {geom.k}, {polarity}, printed MP {geom.mp_unit:.4f} × tag size")


# ----------------------------------------------------------------------------- decode
@cli.command("decode")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--dictionary", default=None, metavar="NAME", help="Only this dictionary's tags decode; report tag numbers."
)
@click.option("--json", "as_json", is_flag=True, help="JSON Lines: one object per image (see README).")
@click.option(
    "--draw",
    "draw_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Write each image with outlines, points, labels and IDs into DIR.",
)
@click.option(
    "--camera",
    type=click.Path(path_type=Path),
    default=None,
    help="Camera intrinsics (JSON camera_matrix/dist_coeffs or fx,fy,cx,cy; or OpenCV YAML).",
)
@click.option("--tag-size", default=None, help=_TAG_SIZE_HELP + "; with --camera gives the pose (in mm).")
@click.option("--no-verify", is_flag=True, help="Decide by order type alone (the paper's rule), no geometric check.")
@_db_options
@_quiet_option
def decode_cmd(
    images: tuple[Path, ...],
    dictionary: str | None,
    as_json: bool,
    draw_dir: Path | None,
    camera: Path | None,
    tag_size: str | None,
    no_verify: bool,
    db_target: str | None,
    quiet: bool,
) -> None:
    """Find Order Type Tags in IMAGE files; print IDs, points, corners, homography (and pose)."""
    from ottag_db.app.decoding import decode_file, load_camera
    from ottag_db.decode.detector import Detector
    from ottag_db.errors import UsageError
    from ottag_db.printing.sheet import parse_length
    from ottag_db.store.dictionaries import dictionary_lookup, neighbour_members
    from ottag_db.store.queries import order_type_numbers

    if (camera is None) != (tag_size is None):
        raise UsageError("--camera and --tag-size go together (pose needs both)")
    cam = load_camera(camera) if camera is not None else None
    size_mm = parse_length(tag_size) if tag_size is not None else None
    if draw_dir is not None:
        draw_dir.mkdir(parents=True, exist_ok=True)
    with _database(db_target, quiet) as db:
        detector = Detector(dictionary_lookup(db, dictionary), verify=not no_verify)
        numbers = order_type_numbers(db)
        near = neighbour_members(db, dictionary) if dictionary else {}
    failed = 0
    for path in images:
        record = decode_file(detector, path, camera=cam, tag_size=size_mm, draw_dir=draw_dir, numbers=numbers)
        if dictionary:
            for r in record.get("rejections", []):
                r["one_flip_from_tag"] = near.get(r["lambda"]) if r["lambda"] else None
        if "error" in record:
            failed += 1
            _note(f"error: {record['error']}")
        if as_json:
            click.echo(json.dumps(record))
            continue
        if "error" in record:
            continue
        dets = record["detections"]
        click.echo(f"{path}: {len(dets)} tag(s), {record['rejected']} rejected candidate(s)")
        for d in dets:
            tag = f" tag {d['tag']}" if d["tag"] is not None else ""
            pose = ""
            if "pose" in d:
                t = d["pose"]["tvec"]
                pose = f" t = ({t[0]:.1f}, {t[1]:.1f}, {t[2]:.1f}) mm"
            click.echo(
                f"  k={d['k']} #{d['order_type']} number {d['number']}{tag} {d['polarity']} "
                f"margin {d['margin_px']:.2f} px{pose}  {d['lambda']}"
            )
    if failed:
        raise _CliError(f"{failed} of {len(images)} image(s) could not be read")


# ----------------------------------------------------------------------------- dictionary
@cli.group("dictionary", cls=_Group)
def dictionary_group() -> None:
    """Named tag dictionaries with stable numbers and a minimum flip distance."""


@dictionary_group.command("create")
@click.argument("name")
@click.option("--k", "ks", type=click.IntRange(3, 8), multiple=True, help="Only these point counts (repeatable).")
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
@_db_options
@_quiet_option
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
    from ottag_db.store.dictionaries import DictionaryOptions, create_dictionary
    from ottag_db.store.numbering import COMPLETE_COUNTS

    opts = DictionaryOptions(
        ks=ks,
        min_mp=min_mp,
        matchable=matchable,
        polarity=polarity,
        include_mirrors=include_mirrors,
        min_flip_distance=min_flip_distance,
        max_size=max_size,
    )
    with _database(db_target, quiet) as db:
        bar = _Progress("flip graph", quiet)
        try:
            info = create_dictionary(db, name, opts, progress=bar)
        finally:
            bar.close()
    click.echo(f"dictionary {info.name}: {len(info.members)} tags, min flip distance {info.min_flip_distance}")
    for k, n in info.counts().items():
        click.echo(f"  k = {k}: {n} tags (of {COMPLETE_COUNTS.get(k, '?')} order types)")


@dictionary_group.command("list")
@_db_options
@_quiet_option
def dictionary_list(db_target: str | None, quiet: bool) -> None:
    """List dictionaries."""
    from ottag_db.store.dictionaries import list_dictionaries

    with _database(db_target, quiet) as db:
        rows = list_dictionaries(db)
    for name, dist, n, created in rows:
        click.echo(f"{name}\t{n} tags\tmin flip distance {dist}\tcreated {created:%Y-%m-%d %H:%M}")
    _note(f"{len(rows)} dictionar{'y' if len(rows) == 1 else 'ies'}", quiet)


@dictionary_group.command("show")
@click.argument("name")
@_db_options
@_quiet_option
def dictionary_show(name: str, db_target: str | None, quiet: bool) -> None:
    """Show a dictionary's members."""
    from ottag_db.store.dictionaries import get_dictionary

    with _database(db_target, quiet) as db:
        info = get_dictionary(db, name)
    click.echo(f"{info.name}: {len(info.members)} tags, min flip distance {info.min_flip_distance}")
    click.echo(f"parameters: {json.dumps(info.parameters, sort_keys=True)}")
    click.echo(f"{'tag':>5} {'number':>6} {'k':>2} {'MP':>7} {'polarity':>8}  lambda")
    for m in info.members:
        num = "-" if m.universal_number is None else str(m.universal_number)
        click.echo(f"{m.number:>5} {num:>6} {m.k:>2} {m.mp:>7.3f} {m.polarity:>8}  {m.lambda_text}")


@dictionary_group.command("delete")
@click.argument("name")
@_db_options
@_quiet_option
def dictionary_delete(name: str, db_target: str | None, quiet: bool) -> None:
    """Delete a dictionary."""
    from ottag_db.store.dictionaries import delete_dictionary

    with _database(db_target, quiet) as db:
        n = delete_dictionary(db, name)
    click.echo(f"deleted dictionary {name} ({n} tags)")


@dictionary_group.command("export")
@click.argument("name")
@click.option("--format", "fmt", type=click.Choice(["json", "csv"]), default="json", show_default=True)
@click.option("--output", "-o", type=click.Path(path_type=Path), default=None, help="File to write [default: stdout].")
@_db_options
@_quiet_option
def dictionary_export(name: str, fmt: str, output: Path | None, db_target: str | None, quiet: bool) -> None:
    """Export a dictionary (everything another implementation needs) as JSON or CSV."""
    from ottag_db.store.dictionaries import export_dictionary

    with _database(db_target, quiet) as db:
        text = export_dictionary(db, name, fmt)
    if output is None:
        click.echo(text, nl=not text.endswith("\n"))
    else:
        try:
            output.write_text(text if text.endswith("\n") else text + "\n", encoding="utf-8")
        except OSError as exc:
            raise _CliError(f"{output}: cannot write ({exc.strerror})") from exc
        _note(f"wrote {output}", quiet)


@dictionary_group.command("import")
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--name", default=None, help="Store under this name instead of the file's.")
@_db_options
@_quiet_option
def dictionary_import(file: Path, name: str | None, db_target: str | None, quiet: bool) -> None:
    """Import a dictionary from its JSON export (its order types must be in the database)."""
    from ottag_db.errors import DictionaryError
    from ottag_db.store.dictionaries import import_dictionary

    try:
        text = file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DictionaryError(f"{file}: cannot read ({exc})") from exc
    with _database(db_target, quiet) as db:
        info = import_dictionary(db, text, source=str(file), name=name)
    click.echo(f"imported dictionary {info.name}: {len(info.members)} tags")


# ----------------------------------------------------------------------------- db
@cli.group("db", cls=_Group)
def db_group() -> None:
    """Schema migrations (applied automatically whenever a command opens a database)."""


@db_group.command("current")
@_db_options
def db_current(db_target: str | None) -> None:
    """Print the database's schema revision and the newest one this tool knows."""
    db = open_database(db_target, migrate=False)
    try:
        cur = db.current_revision()
    finally:
        db.close()
    click.echo(f"current: {cur or '(empty)'}")
    click.echo(f"head:    {head_revision()}")


@db_group.command("upgrade")
@_db_options
@_quiet_option
def db_upgrade(db_target: str | None, quiet: bool) -> None:
    """Migrate the database to the newest schema (backing up an older file first)."""
    with _database(db_target, quiet) as db:
        click.echo(f"at revision {db.current_revision()}")


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="ottag-db")
