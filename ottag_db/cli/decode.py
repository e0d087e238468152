"""The ``decode`` command: find tags in image and video files and print what was read."""

from __future__ import annotations

import itertools
import json
import sys
from pathlib import Path
from typing import Any

import click

from ottag_db.cli.common import TAG_SIZE_HELP, CliError, db_options, note, open_db, quiet_option

__all__ = ["decode_cmd"]


class _FrameBar:
    """A progress bar on stderr per video: frames read of the total, or a count when unknown."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.path: Path | None = None
        self._bar: Any = None
        self._done = 0

    def __call__(self, path: Path, done: int, total: int) -> None:
        if self.quiet:
            return
        if path != self.path:
            self.close()
            self.path = path
            label = f"{path.name} (frames)"
            if total > 0:
                self._bar = click.progressbar(length=total, label=label, file=sys.stderr, show_pos=True)
            else:
                self._bar = click.progressbar(itertools.repeat(None), label=label, file=sys.stderr, show_pos=True)
            self._bar.__enter__()
        if self._bar is not None:
            self._bar.update(done - self._done)
        self._done = done

    def close(self) -> None:
        """End the current bar."""
        if self._bar is not None:
            self._bar.__exit__(None, None, None)
        self._bar = None
        self.path = None
        self._done = 0


def _print_image(path: str, record: dict[str, Any]) -> None:
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


@click.command("decode")
@click.argument("inputs", nargs=-1, required=True, metavar="IMAGE|VIDEO...", type=click.Path(path_type=Path))
@click.option(
    "--dictionary", default=None, metavar="NAME", help="Only this dictionary's tags decode; report tag numbers."
)
@click.option(
    "--dictionary-file",
    type=click.Path(path_type=Path),
    default=None,
    metavar="FILE.json",
    help="Decode with a dictionary export alone (`dictionary export --format json`), no database; "
    "report its tag numbers.",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="JSON Lines: one object per image, one per decoded video frame (with frame and time_s; see README).",
)
@click.option(
    "--draw",
    "draw",
    type=click.Path(path_type=Path),
    default=None,
    metavar="DIR|OUT.mp4",
    help="Annotated outlines, points, labels and IDs. DIR: <stem>_decoded.png per image, <stem>_decoded.mp4 "
    "per video. A path ending in .mp4/.m4v/.mov/.mkv/.avi: the annotated video of the one video input.",
)
@click.option(
    "--every",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    metavar="N",
    help="Videos: decode every N-th frame (0, N, 2N, …); an annotated video then has the decoded frames at fps/N.",
)
@click.option(
    "--camera",
    type=click.Path(path_type=Path),
    default=None,
    help="Camera intrinsics (JSON camera_matrix/dist_coeffs or fx,fy,cx,cy; or OpenCV YAML).",
)
@click.option("--tag-size", default=None, help=TAG_SIZE_HELP + "; with --camera gives the pose (in mm).")
@click.option("--no-verify", is_flag=True, help="Decide by order type alone (the paper's rule), no geometric check.")
@click.option(
    "--fast",
    is_flag=True,
    help="Skip the last-resort candidate passes: frames without a tag take a third of the time; "
    "some tags seen from about 82° on or smeared by a long motion are not read (see the decoding guide).",
)
@db_options
@quiet_option
def decode_cmd(
    inputs: tuple[Path, ...],
    dictionary: str | None,
    dictionary_file: Path | None,
    as_json: bool,
    draw: Path | None,
    every: int,
    camera: Path | None,
    tag_size: str | None,
    no_verify: bool,
    fast: bool,
    db_target: str | None,
    quiet: bool,
) -> None:
    """Find Order Type Tags in IMAGE or VIDEO files; print IDs, points, corners, homography (and pose).

    A file OpenCV recognises as an image is decoded as one; any other file is opened as a video
    (MP4, AVI, MKV, … whatever OpenCV's FFmpeg reads) and every (N-th) frame is decoded with the
    same detector. Human-readable output summarises each video: frames, and each tag seen with
    the frames it was in; --json gives every frame. With --dictionary-file only that file's
    tags decode, verified against its points, and no database is opened (--db is not used).
    """
    from ottag_db.app.decode_batch import decode_inputs, decode_options, prepare_decoding, prepare_file_decoding
    from ottag_db.app.video import VideoTally

    if dictionary_file is not None and dictionary is not None:
        raise click.UsageError("--dictionary NAME (in the database) and --dictionary-file FILE exclude each other")
    options = decode_options(camera, tag_size, draw, every=every)
    if dictionary_file is not None:
        setup = prepare_file_decoding(dictionary_file, verify=not no_verify, fast=fast)
    else:
        with open_db(db_target, quiet) as db:
            setup = prepare_decoding(db, dictionary, verify=not no_verify, fast=fast)
    bar = _FrameBar(quiet)
    failed: list[str] = []
    tally: VideoTally | None = None

    def flush() -> None:
        nonlocal tally
        bar.close()
        if tally is not None:
            for line in tally.lines():
                click.echo(line)
            tally = None

    try:
        for record in decode_inputs(setup, inputs, options, progress=bar):
            path = record["image"]
            if tally is not None and ("frame" not in record or tally.image != path):
                flush()
            if "error" in record:
                bar.close()
                failed.append(record["error"])
                if len(inputs) > 1:
                    note(f"error: {record['error']}")
            if as_json:
                click.echo(json.dumps(record))
            elif "error" in record:
                pass
            elif "frame" in record:
                if tally is None:
                    tally = VideoTally(path)
                tally.add(record)
            else:
                _print_image(path, record)
    finally:
        flush()
    if failed:
        if len(inputs) == 1:
            raise CliError(failed[0])
        raise CliError(f"{len(failed)} of {len(inputs)} file(s) could not be read")
