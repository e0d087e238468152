"""The ``generate`` command: enumerate and realize every order type, write the data files."""

from __future__ import annotations

import re
from pathlib import Path

import click

from ottag_db.cli.common import StageProgress, quiet_option

__all__ = ["generate_cmd"]

_ADDRESS = re.compile(r"^(?:[a-z][a-z0-9+.-]*://)?[^\s/:]+(?::\d+)?/?$", re.IGNORECASE)


def _check_address(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """A Dask scheduler address such as ``tcp://host:8786`` (or None)."""
    if value is not None and not _ADDRESS.match(value):
        raise click.BadParameter(f"{value!r} is not a scheduler address; expected e.g. tcp://host:8786")
    return value


@click.command("generate")
@click.option(
    "--max-k", type=click.IntRange(3, 9), default=8, show_default=True, help="Largest number of points (9: see README)."
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=Path("data"),
    show_default=True,
    help="Folder for ottag-kNN.b08 files and manifest.json.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Same seed, same files.")
@click.option(
    "--jobs",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    help="Worker processes: above 1, a local Dask cluster of N workers (one thread each) realizes the sets.",
)
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    default=None,
    callback=_check_address,
    help="Realize on an existing Dask cluster (e.g. tcp://host:8786; its workers need ottag-db installed).",
)
@click.option(
    "--work-dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Folder that keeps finished batches so an interrupted run resumes [default: OUT.partial beside OUT].",
)
@quiet_option
def generate_cmd(
    max_k: int, out_dir: Path, seed: int, jobs: int, scheduler: str | None, work_dir: Path | None, quiet: bool
) -> None:
    """Enumerate every order type of 3 … MAX_K points and realize each on the 8-bit grid with maximal MP.

    Writes one set per reflection pair (drop-in replacements of Aichholzer's otypesNN.b08)
    plus a manifest; `ottag-db import OUT/ottag-kNN.b08 --with-mirrors` loads them. The same
    seed gives byte-identical files whatever the workers (--jobs, --scheduler) and --max-k (on
    one platform); with the bundled seed each file is compared with the bundled one.
    Interrupted (Ctrl-C), the same command resumes: finished batches are kept in the work
    folder, which is deleted once the files are written.
    """
    from ottag_db.app.generating import default_work_dir, generate_database

    work = work_dir if work_dir is not None else default_work_dir(out_dir)
    bar = StageProgress(quiet)
    try:
        rep = generate_database(
            max_k=max_k, out_dir=out_dir, seed=seed, jobs=jobs, progress=bar, scheduler=scheduler, work_dir=work
        )
    except KeyboardInterrupt:
        bar.close()
        click.echo(f"interrupted: finished batches are kept in {work}; run the same command again to resume", err=True)
        raise SystemExit(130) from None
    finally:
        bar.close()
    for k in sorted(rep.records):
        same = rep.bundled.get(k)
        note = ""
        if same is not None:
            note = (
                ", identical to the bundled file"
                if same.identical
                else f", differs from the bundled file in {same.differing} of {same.records} records"
            )
        click.echo(
            f"k = {k}: {rep.records[k]} order types up to reflection ({rep.with_mirrors[k]} with mirrors), "
            f"min MP {rep.mp_min[k]:.2f}{note} -> {rep.files[k]}"
        )
        passes = rep.passes.get(k, ())
        if passes:
            click.echo(
                f"  {rep.records[k] - rep.achiral[k]} chiral pairs, {rep.achiral[k]} achiral; enumerated from "
                f"{sum(p.bases for p in passes)} realizations of {k - 1} points in {len(passes)} passes",
                err=True,
            )
    if any(not c.identical for c in rep.bundled.values()):
        click.echo(
            "note: the same seed gives byte-identical files on one platform (any --jobs, any --max-k); "
            "the floating point of the enumeration and the optimization depends on the CPU's instruction set and the "
            "NumPy/SciPy/OpenBLAS builds, so this machine realizes some sets differently from the one that "
            "made the bundled data (see README, 'The bundled database')",
            err=True,
        )
    click.echo(f"manifest: {rep.manifest}")
    click.echo(
        f"time: {rep.seconds['total']:.0f} s (enumerate {rep.seconds['enumerate']:.0f} s, "
        f"realize {rep.seconds['realize']:.0f} s)"
    )
