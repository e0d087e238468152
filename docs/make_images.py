"""Regenerate every picture and plot of the documentation into ``docs/img/``.

Usage: python docs/make_images.py [--trials N] [--frames N] [--views N] [--images-only]

Needs ``pip install '.[test,bench]'`` (pypdfium2 rasterizes the PDFs; pupil-apriltags and
matplotlib are the benchmarks' peer and plots). In a temporary folder it runs the project's own
commands: ``ottag-db import`` (the bundled data), ``render`` (a tag), ``export`` (a sheet),
``board create`` (a calibration board) and ``decode --draw`` on a photo of the sheet (the sheet's
PDF rasterized and seen in perspective, with blur and noise, as in the guide "Decoding images and
video"). Then the benchmarks with ``--plot`` into ``docs/img/``: ``decode_sweeps.py --trials N
--paired`` (default 30 scenes per condition and polarity), ``decode_speed.py`` (default 100
frames), ``decode_many.py 4``, ``pose_accuracy.py`` (30 poses), ``calibration.py`` (default 20
views, seed 0) and ``decode_degraded.py`` (101 ray-traced poses, seed 7; skipped without POV-Ray,
``apt-get install povray``). Each benchmark's printout is kept in
``docs/_build/benchmarks/NAME.txt``; the figures of ``docs/benchmarks.md`` come from there. About
6–8 minutes on two cores with the defaults, and about 10 more for ``decode_degraded.py``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

DOCS = Path(__file__).resolve().parent
IMG = DOCS / "img"
BENCH = DOCS.parent / "benchmarks"
LOGS = DOCS / "_build" / "benchmarks"


def ottag(folder: Path, *args: str) -> str:
    """Run ``ottag-db --db ottag.sqlite ARGS`` in ``folder``; its stdout."""
    cmd = [sys.executable, "-m", "ottag_db", "--quiet", "--db", str(folder / "ottag.sqlite"), *args]
    print("$ ottag-db " + " ".join(args), flush=True)
    return subprocess.run(cmd, cwd=folder, check=True, capture_output=True, text=True).stdout


def rasterize(pdf: Path, px_per_mm: float) -> np.ndarray:
    """Page 1 of ``pdf`` as a grey image at ``px_per_mm`` (rendered at 4× and reduced by area averaging)."""
    import pypdfium2 as pdfium

    doc = pdfium.PdfDocument(str(pdf))
    page = doc[0].render(scale=4 * px_per_mm * 25.4 / 72, grayscale=True).to_numpy()
    doc.close()
    grey = np.ascontiguousarray(page[..., 0] if page.ndim == 3 else page)
    return np.asarray(cv2.resize(grey, (grey.shape[1] // 4, grey.shape[0] // 4), interpolation=cv2.INTER_AREA))


def photo_of(page: np.ndarray, size: tuple[int, int] = (1280, 960), seed: int = 3) -> np.ndarray:
    """The page seen in perspective: corners of its upper part moved in, grey background, blur, noise."""
    w, h = size
    top = page[: page.shape[0] * 2 // 5]  # the first rows of tags
    ph, pw = top.shape
    src = np.float32([[0, 0], [pw, 0], [pw, ph], [0, ph]])
    dst = np.float32([[170, 120], [1110, 60], [1230, 900], [40, 820]])
    hom = cv2.getPerspectiveTransform(src, dst)
    frame = cv2.warpPerspective(top, hom, (w, h), flags=cv2.INTER_AREA, borderValue=90)
    frame = cv2.GaussianBlur(frame.astype(np.float64), (0, 0), 0.8)
    frame += np.random.default_rng(seed).normal(0, 1.0, frame.shape)
    return np.clip(np.rint(frame), 0, 255).astype(np.uint8)


def save_small(image: np.ndarray, path: Path, width: int) -> None:
    """Write ``image`` reduced to ``width`` px (area averaging) as a compressed PNG."""
    scale = width / image.shape[1]
    if scale < 1:
        image = cv2.resize(image, (width, round(image.shape[0] * scale)), interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(path), image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"image: {path} ({path.stat().st_size // 1024} KB)", flush=True)


def pictures(folder: Path) -> None:
    """A tag, a sheet, a board and a decoded photo of the sheet, by the project's commands."""
    ottag(folder, "import")
    best = ottag(folder, "list", "--k", "8", "--min-mp", "12", "--matchable", "--format", "csv").splitlines()[1]
    tag_id = best.split(",")[0]
    ottag(folder, "render", tag_id, "tag.png", "--px", "240")
    shutil.copyfile(folder / "tag.png", IMG / "tag.png")
    print(f"image: {IMG / 'tag.png'}")
    ottag(folder, "export", "--k", "8", "--min-mp", "10", "--tag-size", "40mm", "tags.pdf")
    page = rasterize(folder / "tags.pdf", 8.0)
    save_small(page, IMG / "sheet.png", 420)
    ottag(folder, "board", "create", "board.pdf", "--rows", "4", "--cols", "3", "--tag-size", "40mm")
    save_small(rasterize(folder / "board.pdf", 4.0), IMG / "board.png", 420)
    cv2.imwrite(str(folder / "photo.png"), photo_of(page))
    print(ottag(folder, "decode", "photo.png", "--draw", "drawn"), end="")
    save_small(cv2.imread(str(folder / "drawn" / "photo_decoded.png")), IMG / "decoded.png", 640)


def benchmark(name: str, *args: str) -> None:
    """Run ``benchmarks/NAME.py ARGS``, print and keep its printout."""
    print(f"$ python benchmarks/{name}.py {' '.join(args)}", flush=True)
    done = subprocess.run(
        [sys.executable, str(BENCH / f"{name}.py"), *args], cwd=DOCS.parent, capture_output=True, text=True
    )
    LOGS.mkdir(parents=True, exist_ok=True)
    (LOGS / f"{name}.txt").write_text(done.stdout, encoding="utf-8")
    print(done.stdout, end="", flush=True)
    if done.returncode != 0 and "plot:" not in done.stdout:
        sys.exit(f"benchmarks/{name}.py failed ({done.returncode}):\n{done.stderr}")
    if done.returncode != 0:
        # pupil_apriltags can corrupt the heap when its detector is freed at exit
        # (pupil-labs/apriltags issue 39): the printout and the plot are complete.
        print(f"(benchmarks/{name}.py ended with {done.returncode} after writing its plot)", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=30, help="decode_sweeps.py scenes per condition [30]")
    parser.add_argument("--frames", type=int, default=100, help="decode_speed.py frames [100]")
    parser.add_argument("--views", type=int, default=20, help="calibration.py views [20]")
    parser.add_argument("--images-only", action="store_true", help="the pictures, not the benchmark plots")
    args = parser.parse_args()
    IMG.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        pictures(Path(tmp))
    if args.images_only:
        return
    benchmark("decode_sweeps", "--trials", str(args.trials), "--paired", "--plot", str(IMG / "decode_sweeps.png"))
    benchmark("decode_speed", str(args.frames), "--plot", str(IMG / "decode_speed.png"))
    benchmark("decode_many", "4", "--plot", str(IMG / "decode_many.png"))
    benchmark("pose_accuracy", "--quiet", "--plot", str(IMG / "pose_accuracy.png"))
    benchmark("calibration", str(args.views), "0", "--plot", str(IMG / "calibration.png"))
    if shutil.which("povray") is None:
        print("decode_degraded.py skipped: POV-Ray is not installed (apt-get install povray)", flush=True)
    else:
        benchmark("decode_degraded", "--seed", "7", "--quiet", "--plot", str(IMG / "decode_degraded.png"))


if __name__ == "__main__":
    main()
