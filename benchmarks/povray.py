"""Ray-traced frames of one textured planar square, by POV-Ray (``apt-get install povray``).

Usage: python benchmarks/povray.py [--poses N] [--cache DIR] [--camera {640,1280,both}]
       (the camera check below)

A square patch (an image map from a grey texture: a marker with its white border), or a
rectangular one (a board's page), is posed in front of a pinhole :class:`Camera`: by default
(:data:`CAMERA`) 640×480 pixels with f = 700 px, the calibration benchmark's
(:data:`CALIBRATION_CAMERA`) 1280×960 with f = 1000 px; the principal point at the image centre
((319.5, 239.5) and (639.5, 479.5)), pixel centres at integer coordinates as in OpenCV. POV-Ray's
perspective camera is given ``direction`` = f, ``right`` = width and ``up`` = height in pixel
units, so its focal length is f pixels exactly; POV-Ray's left-handed frame (y up) is OpenCV's
(y down) with y negated. A large grey wall 3 m behind the patch's centre fills the
surroundings; one point light up and to the left of the camera and an ambient term light the
scene (the patch casts no shadow on the wall); adaptive antialiasing (``+A0.05 +AM2 +R3``, no
jitter), or every pixel supersampled (``Renderer(..., antialias="full")``, :data:`ANTIALIAS`).
The texture is mapped to reflectances from ink (0.05) to paper (0.9); the pipeline is linear
(gamma 1 in and out).

:class:`Renderer` renders a batch of scenes with at most two POV-Ray processes at once (one
thread each), each in its own temporary folder, and keeps each frame as a PNG in a cache folder
keyed by a hash of the scene file and the texture, so a rerun reads them back. Each frame comes
with the true corners of the texture's black square (the middle two thirds of the patch), projected by
the camera matrix of the renderer's camera.

Run as a script, it checks each camera: a plain black square on its white border rendered at
``--poses`` poses like the benchmarks' (1.5 m for the 640×480 camera, tilt −50…50°, roll 30°;
for another camera the distance and the spread of centres scaled so the square takes the same
part of the frame), its four sides located on the frame by edge fits (50 % crossings of the
profiles across each side, a line fitted per side, corners as intersections), against the
projected true corners; once on the frames as rendered, once on the frames smoothed by a Gaussian
of σ 1 px (straight edges stay in place; the interpolated profile of a sharp edge crosses its mid
level up to ±0.1 px off with the edge's phase against the pixel grid, which a side's line fit
does not always average out).
"""

from __future__ import annotations

import argparse
import hashlib
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

WIDTH, HEIGHT, FOCAL = 640, 480, 700.0
#: The default camera matrix (pixel centres at integers).
K = np.array([[FOCAL, 0, (WIDTH - 1) / 2], [0, FOCAL, (HEIGHT - 1) / 2], [0, 0, 1]])
#: The point light's default position (POV-Ray's frame: x right, y up, z forward; m): up and to the left.
LIGHT = (-0.4, 0.6, 0.0)
#: Reflectance of the texture's black (ink) and white (paper).
INK, PAPER = 0.05, 0.9
#: Render options: antialiasing (adaptive, threshold 0.05, depth 3, no jitter), one thread.
OPTIONS = ("+A0.05", "+AM2", "+R3", "-J", "+WT1", "-D", "-V", "+FN8", "Display_Gamma=1.0", "File_Gamma=1.0")
#: The antialiasing a :class:`Renderer` can use. ``"adaptive"`` (:data:`OPTIONS`): a pixel is
#: supersampled only where the samples at its corners differ by more than 0.05, so a feature
#: thinner than a pixel that falls between them is missed (a tag's triangles at a grazing view
#: become slivers under a pixel wide, and whole stretches of them render as ink). ``"full"``:
#: every pixel supersampled (threshold 0), as a camera integrates the light over each pixel's
#: area; about 3× the render time.
ANTIALIAS = {"adaptive": OPTIONS, "full": ("+A0.0", *OPTIONS[1:])}
#: The black square's corners in texture coordinates (x right, y down; the patch, black square plus a
#: white border of a quarter side, is the unit square).
SQUARE = np.array([[1, 1], [5, 1], [5, 5], [1, 5]]) / 6

_U8 = NDArray[np.uint8]
_F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Camera:
    """A pinhole camera of ``width`` × ``height`` pixels, focal length ``focal`` px, principal point at
    the image centre ((width − 1) / 2, (height − 1) / 2), no distortion."""

    width: int
    height: int
    focal: float

    @property
    def matrix(self) -> _F64:
        """The 3×3 camera matrix (OpenCV; pixel centres at integers)."""
        f, cx, cy = self.focal, (self.width - 1) / 2, (self.height - 1) / 2
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


#: The decoding benchmarks' camera (``K``).
CAMERA = Camera(WIDTH, HEIGHT, FOCAL)
#: The calibration benchmark's camera: 1280×960, f = 1000 px, principal point (639.5, 479.5).
CALIBRATION_CAMERA = Camera(1280, 960, 1000.0)


def rotation(axis: Sequence[float], degrees: float) -> _F64:
    """Rotation matrix about ``axis`` by ``degrees``."""
    vec = np.asarray(axis, np.float64)
    r_mat, _ = cv2.Rodrigues(vec / np.linalg.norm(vec) * np.radians(degrees))
    return np.asarray(r_mat, np.float64)


def pose(
    tilt: float, roll: float, distance: float, centre_px: Sequence[float], camera: Camera = CAMERA
) -> tuple[_F64, _F64]:
    """The patch rolled by ``roll``° about its normal, then tilted by ``tilt``° about the camera's
    vertical axis, its centre ``distance`` m away on the ray through pixel ``centre_px``."""
    r_mat = rotation((0, 1, 0), tilt) @ rotation((0, 0, 1), roll)
    ray = np.linalg.solve(camera.matrix, [centre_px[0], centre_px[1], 1.0])
    return r_mat, distance * ray / np.linalg.norm(ray)


def project(
    r_mat: _F64, t: _F64, side: float, uv: _F64 = SQUARE, camera: Camera = CAMERA, height: float | None = None
) -> _F64:
    """Pixels of texture points ``uv`` (unit patch, x right, y down) of a patch ``side`` m wide
    (``height`` m high; default: square), its centre at ``t``."""
    h = side if height is None else height
    local = np.column_stack([(uv[:, 0] - 0.5) * side, (uv[:, 1] - 0.5) * h, np.zeros(len(uv))])
    cam = local @ r_mat.T + t
    pix = cam @ camera.matrix.T
    return np.asarray(pix[:, :2] / pix[:, 2:], np.float64)


def scene_source(
    texture: str,
    r_mat: _F64,
    t: _F64,
    side: float,
    camera: Camera = CAMERA,
    height: float | None = None,
    light: Sequence[float] = LIGHT,
) -> str:
    """POV-Ray scene: the camera, the light (at ``light``, POV-Ray's frame), the wall and the patch
    (``side`` m wide, ``height`` m high, default square; its centre at ``t``) mapped from ``texture``."""
    h = side if height is None else height
    flip = np.diag([1.0, -1.0, 1.0])  # OpenCV camera frame (y down) -> POV-Ray's (y up)
    rows = [
        flip @ r_mat[:, 0] * side,  # texture x (right)
        -(flip @ r_mat[:, 1]) * h,  # texture y of POV-Ray's image map (up) = -(patch y, down)
        flip @ r_mat[:, 2] * side,
        flip @ (t + r_mat @ np.array([-side / 2, h / 2, 0.0])),  # image map origin: bottom-left
    ]
    matrix = ", ".join(f"{v:.12g}" for row in rows for v in row)
    w, ht, f = camera.width, camera.height, camera.focal
    return f"""#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ perspective location <0, 0, 0> direction <0, 0, {f}> right <{w}, 0, 0> up <0, {ht}, 0> }}
light_source {{ <{light[0]:g}, {light[1]:g}, {light[2]:g}> color rgb 1 }}
background {{ color rgb 0.3 }}
plane {{ z, {t[2] + 3.0:.6f} pigment {{ color rgb 0.4 }} finish {{ ambient 0.3 diffuse 0.7 }} }}
polygon {{ 5, <0, 0>, <1, 0>, <1, 1>, <0, 1>, <0, 0>
  pigment {{ image_map {{ png "{texture}" gamma 1.0 once interpolate 2 }} }}
  finish {{ ambient 0.3 diffuse 0.7 }}
  no_shadow
  matrix <{matrix}>
}}
"""


@dataclass(frozen=True)
class Scene:
    """One frame to render: a grey texture (the unit patch) posed by ``r_mat``, ``t`` (m; the patch's
    centre), ``side`` m wide and ``height`` m high (None: square), lit from ``light`` (POV-Ray's frame, m)."""

    texture: _U8
    r_mat: _F64
    t: _F64
    side: float
    height: float | None = None
    light: tuple[float, float, float] = LIGHT


@dataclass(frozen=True)
class Frame:
    """A rendered grey frame and the true corners of the texture's black square (pixels)."""

    image: _U8
    corners: _F64


def _texture_png(texture: _U8) -> bytes:
    """The texture mapped to reflectances INK … PAPER, as PNG bytes."""
    levels = INK + (PAPER - INK) * texture.astype(np.float64) / 255.0
    ok, buf = cv2.imencode(".png", np.rint(255 * levels).astype(np.uint8))
    assert ok
    return bytes(buf)


class Renderer:
    """POV-Ray frames of :class:`Scene` s seen by ``camera``, at most ``processes`` (≤ 2) renders at a
    time, cached in ``cache``."""

    def __init__(self, cache: Path, processes: int = 2, camera: Camera = CAMERA, antialias: str = "adaptive") -> None:
        if shutil.which("povray") is None:
            raise RuntimeError("POV-Ray is not installed (Debian: apt-get install -y povray)")
        self.cache = cache
        self.camera = camera
        self.options = ANTIALIAS[antialias]  # (the cache key holds them: frames of each are kept apart)
        self.processes = max(1, min(2, processes))
        self.cache.mkdir(parents=True, exist_ok=True)
        self._pngs: dict[int, tuple[_U8, bytes, str]] = {}  # id -> (the texture, kept alive; PNG; hash)
        self.rendered = 0  # frames rendered (not read from the cache) by this renderer
        self.seconds = 0.0  # wall time of the batches that rendered

    def _png(self, texture: _U8) -> tuple[bytes, str]:
        if id(texture) not in self._pngs:
            png = _texture_png(texture)
            self._pngs[id(texture)] = (texture, png, hashlib.sha256(png).hexdigest())
        return self._pngs[id(texture)][1:]

    def _one(self, scene: Scene) -> _U8:
        png, digest = self._png(scene.texture)
        source = scene_source("texture.png", scene.r_mat, scene.t, scene.side, self.camera, scene.height, scene.light)
        key = hashlib.sha256("\n".join([source, digest, *self.options]).encode()).hexdigest()[:32]
        path = self.cache / f"{key}.png"
        if not path.exists():
            with tempfile.TemporaryDirectory(prefix="povray-") as tmp:
                folder = Path(tmp)
                (folder / "texture.png").write_bytes(png)
                (folder / "scene.pov").write_text(source, encoding="utf-8")
                size = (f"+W{self.camera.width}", f"+H{self.camera.height}")
                cmd = ["povray", "+Iscene.pov", "+Oframe.png", *size, *self.options]
                done = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
                if done.returncode != 0 or not (folder / "frame.png").exists():
                    raise RuntimeError(f"povray failed ({done.returncode}): {done.stderr[-800:]}")
                shutil.move(folder / "frame.png", path.with_suffix(".tmp"))
                path.with_suffix(".tmp").replace(path)
                self.rendered += 1
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise RuntimeError(f"cannot read {path}")
        return np.asarray(image, np.uint8)

    def render(self, scenes: Sequence[Scene], progress: Callable[[int, int], None] | None = None) -> list[Frame]:
        """The frames of ``scenes`` in order; ``progress(done, total)`` after each."""
        import time

        start, before = time.perf_counter(), self.rendered
        images: list[_U8] = []
        with ThreadPoolExecutor(max_workers=self.processes) as pool:
            for image in pool.map(self._one, scenes):
                images.append(image)
                if progress is not None:
                    progress(len(images), len(scenes))
        if self.rendered > before:
            self.seconds += time.perf_counter() - start
        return [
            Frame(img, project(s.r_mat, s.t, s.side, camera=self.camera, height=s.height))
            for img, s in zip(images, scenes, strict=True)
        ]


def square_patch(side_px: int = 800) -> _U8:
    """A plain black square ``side_px`` wide on a white border of a quarter side (the checks' texture)."""
    q = side_px // 4
    patch = np.full((side_px + 2 * q, side_px + 2 * q), 255, np.uint8)
    patch[q : q + side_px, q : q + side_px] = 0
    return patch


def measure_corners(image: _U8, approx: _F64, reach: float = 5.0, smooth: float = 0.0) -> _F64:
    """Corners of a dark quadrilateral on a bright surround, located on ``image`` by edge fits.

    Along each side of ``approx`` (corners in order, within a pixel or two of the truth), between
    15 % and 85 % of its length, the image is sampled across the side (±``reach`` px, bilinear);
    each profile's crossing of the mid level between its ends gives an edge point, a line is
    fitted to a side's points, and the corners are the intersections of adjacent lines. ``smooth``:
    the image is first blurred by a Gaussian of this σ (px), which leaves straight edges in place
    but removes the error of interpolating a sharp edge's profile (up to ±0.1 px with the edge's
    phase against the pixel grid, which the line fit averages out only where the phase varies).
    """
    grey = image.astype(np.float32)
    if smooth > 0:
        grey = np.asarray(cv2.GaussianBlur(grey, (0, 0), smooth), np.float32)
    lines = []
    for i in range(4):
        a, b = approx[i], approx[(i + 1) % 4]
        along = (b - a) / np.linalg.norm(b - a)
        normal = np.array([-along[1], along[0]])
        offsets = np.linspace(-reach, reach, int(8 * reach) + 1)
        points = []
        for s in np.linspace(0.15, 0.85, 40):
            base = a + s * (b - a)
            xy = base + offsets[:, None] * normal
            prof = cv2.remap(grey, xy[:, :1].astype(np.float32), xy[:, 1:].astype(np.float32), cv2.INTER_LINEAR)
            prof = prof.ravel().astype(np.float64)
            lo, hi = prof[:4].mean(), prof[-4:].mean()
            mid = (lo + hi) / 2
            above = np.nonzero(np.diff(np.sign(prof - mid)))[0]
            if len(above) != 1:
                continue
            j = above[0]
            frac = (mid - prof[j]) / (prof[j + 1] - prof[j])
            points.append(base + (offsets[j] + frac * (offsets[1] - offsets[0])) * normal)
        pts = np.asarray(points)
        centre = pts.mean(axis=0)
        _, _, vt = np.linalg.svd(pts - centre)
        lines.append((centre, vt[0]))
    corners = []
    for i in range(4):
        (p, d), (q, e) = lines[i - 1], lines[i]
        s = np.linalg.solve(np.column_stack([d, -e]), q - p)
        corners.append(p + s[0] * d)
    return np.asarray(corners)


def check(poses: int, cache: Path, seed: int = 1, camera: Camera = CAMERA) -> float:
    """Render the plain square at ``poses`` poses seen by ``camera`` and print the corner errors
    measured on the frames as rendered and smoothed by σ 1 px; the largest of the latter (px).

    The square (21 cm) is at 1.5 m before the 640×480 camera, f = 700 px; for another camera the
    distance and the spread of its centre are scaled to the same part of the frame.
    """
    renderer = Renderer(cache, camera=camera)
    rng = np.random.default_rng(seed)
    patch = square_patch()
    scale = camera.width / WIDTH
    distance = 1.5 * (camera.focal / FOCAL) / scale
    cx, cy = (camera.width - 1) / 2, (camera.height - 1) / 2
    scenes = []
    for _ in range(poses):
        centre = (cx + scale * rng.uniform(-80, 80), cy + scale * rng.uniform(-60, 60))
        r_mat, t = pose(rng.uniform(-50, 50), 30.0, distance, centre, camera)
        scenes.append(Scene(patch, r_mat, t, 0.21 * 1.5))
    frames = renderer.render(scenes)
    largest = 0.0
    for smooth in (0.0, 1.0):
        found = [measure_corners(f.image, f.corners, smooth=smooth) for f in frames]
        errors = np.array([np.linalg.norm(m - f.corners, axis=1) for m, f in zip(found, frames, strict=True)])
        offsets = np.array([(m - f.corners).mean(axis=0) for m, f in zip(found, frames, strict=True)])
        how = "raw frames" if smooth == 0 else f"frames smoothed σ {smooth:g} px"
        print(
            f"corner check, {camera.width}×{camera.height}, f = {camera.focal:g} px, {how} "
            f"({poses} poses, {4 * poses} corners): measured - projected, mean {errors.mean():.3f} px, "
            f"largest {errors.max():.3f} px; mean offset ({offsets[:, 0].mean():+.3f}, {offsets[:, 1].mean():+.3f}) px"
        )
        largest = float(errors.max())
    print(f"{renderer.rendered} rendered in {renderer.seconds:.1f} s")
    return largest


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--poses", type=int, default=21, help="poses of the check (default 21)")
    parser.add_argument("--cache", type=Path, help="folder of rendered frames (default: a temporary one)")
    parser.add_argument(
        "--camera", choices=("640", "1280", "both"), default="both", help="which camera to check (default both)"
    )
    args = parser.parse_args()
    if args.poses < 1:
        parser.error("--poses must be at least 1")
    cameras = {"640": [CAMERA], "1280": [CALIBRATION_CAMERA], "both": [CAMERA, CALIBRATION_CAMERA]}[args.camera]
    with tempfile.TemporaryDirectory() as tmp:
        for cam in cameras:
            check(args.poses, args.cache if args.cache is not None else Path(tmp), camera=cam)
    sys.exit(0)
