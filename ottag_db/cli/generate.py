"""The ``generate`` command: enumerate and realize every order type, write the data files."""

from __future__ import annotations

from pathlib import Path

import click

from ottag_db.cli.common import StageProgress, quiet_option

__all__ = ["generate_cmd"]


@click.command("generate")
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
@quiet_option
def generate_cmd(max_k: int, out_dir: Path, seed: int, jobs: int, quiet: bool) -> None:
    """Enumerate every order type of 3 … MAX_K points and realize each on the 8-bit grid with maximal MP.

    Writes one set per reflection pair (drop-in replacements of Aichholzer's otypesNN.b08)
    plus a manifest; `ottag-db import OUT/ottag-kNN.b08 --with-mirrors` loads them. The same
    seed gives byte-identical files whatever --jobs and --max-k (on one platform); with the
    bundled seed each file is compared with the bundled one.
    """
    from ottag_db.app.generating import generate_database

    bar = StageProgress(quiet)
    try:
        rep = generate_database(max_k=max_k, out_dir=out_dir, seed=seed, jobs=jobs, progress=bar)
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
