"""The ``calibrate`` command: camera intrinsics from images of a calibration board."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ottag_db.cli.common import Progress, note, quiet_option

__all__ = ["calibrate_cmd"]


@click.command("calibrate")
@click.argument("board_file", metavar="BOARD.board.json", type=click.Path(path_type=Path))
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the result as one JSON object.")
@click.option("-o", "--out", type=click.Path(path_type=Path), default=None, help="Write the camera file (JSON).")
@click.option("--fix-aspect", is_flag=True, help="Keep fx = fy.")
@click.option(
    "--model",
    type=click.Choice(["standard", "rational"]),
    default="standard",
    show_default=True,
    help="standard: k1, k2, p1, p2; rational: OpenCV's rational model (k1 … k6, p1, p2).",
)
@quiet_option
def calibrate_cmd(
    board_file: Path,
    images: tuple[Path, ...],
    as_json: bool,
    out: Path | None,
    fix_aspect: bool,
    model: str,
    quiet: bool,
) -> None:
    """Calibrate a camera from IMAGE files of the printed board BOARD.board.json.

    Every image is decoded with the board's tags only (no database needed); all point and
    corner correspondences go to cv2.calibrateCamera; outlying views and points are dropped
    and the camera is fitted again. Prints fx, fy, cx, cy, the distortion coefficients, the
    RMS error and the per-view errors; -o writes a camera file that `decode --camera` reads.
    """
    from ottag_db.app.boards import read_board
    from ottag_db.app.calibration import CalibrationOptions, calibrate_board, calibration_json, write_camera

    board = read_board(board_file)
    options = CalibrationOptions(model=model, fix_aspect=fix_aspect)
    bar = Progress("decoding images", quiet)
    try:
        result = calibrate_board(board, images, options, progress=bar)
    finally:
        bar.close()
    if out is not None:
        write_camera(result, out)
        note(f"camera file written to {out} (use it with `ottag-db decode --camera {out} --tag-size ...`)", quiet)
    if as_json:
        click.echo(json.dumps(calibration_json(result)))
        return
    w, h = result.image_size
    used = [v for v in result.views if v.used]
    click.echo(f"image size {w} × {h} px, {len(used)} of {len(result.views)} views used, model {result.model}")
    std = result.std_intrinsics
    click.echo(f"fx = {result.fx:.2f} ± {std[0]:.2f} px   fy = {result.fy:.2f} ± {std[1]:.2f} px")
    click.echo(f"cx = {result.cx:.2f} ± {std[2]:.2f} px   cy = {result.cy:.2f} ± {std[3]:.2f} px")
    names = ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]
    click.echo("distortion: " + "  ".join(f"{n} = {v:.5f}" for n, v in zip(names, result.dist_coeffs, strict=False)))
    click.echo(f"RMS reprojection error {result.rms_px:.3f} px")
    click.echo("view  tags  points  rms_px  image")
    for i, v in enumerate(result.views):
        rms = f"{v.rms_px:6.3f}" if v.rms_px is not None else "     -"
        extra = (
            f"  (not used: {v.reason})"
            if not v.used
            else (f"  ({v.dropped_points} outlying point(s) dropped)" if v.dropped_points else "")
        )
        click.echo(f"{i:>4}  {v.tags:>4}  {v.points:>6}  {rms}  {v.image}{extra}")
