"""The ``decode`` command: find tags in image files and print what was read."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ottag_db.cli.common import TAG_SIZE_HELP, CliError, db_options, note, open_db, quiet_option

__all__ = ["decode_cmd"]


@click.command("decode")
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
@click.option("--tag-size", default=None, help=TAG_SIZE_HELP + "; with --camera gives the pose (in mm).")
@click.option("--no-verify", is_flag=True, help="Decide by order type alone (the paper's rule), no geometric check.")
@db_options
@quiet_option
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
    from ottag_db.app.decode_batch import decode_images, decode_options, prepare_decoding

    options = decode_options(camera, tag_size, draw_dir)
    with open_db(db_target, quiet) as db:
        setup = prepare_decoding(db, dictionary, verify=not no_verify)
    failed = 0
    for path, record in zip(images, decode_images(setup, images, options), strict=True):
        if "error" in record:
            failed += 1
            note(f"error: {record['error']}")
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
        raise CliError(f"{failed} of {len(images)} image(s) could not be read")
