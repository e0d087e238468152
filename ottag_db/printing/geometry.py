"""Tag geometry: a point set placed in the data area with its layout, tones and sizes (no drawing)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ottag_db.core.geometry import as_point_batch, maximal_perturbations
from ottag_db.core.placement import DEFAULT_INNER_MARGIN, apply_placements, tag_placements
from ottag_db.core.types import POLARITIES, QUIET_ZONE, Polarity
from ottag_db.errors import ExportError, UsageError

__all__ = [
    "DEFAULT_QUIET_ZONE_RATIO",
    "TagGeometry",
    "build_tag_geometries",
    "build_tag_geometry",
    "default_quiet_zone",
]

#: Default quiet zone width as a fraction of the tag size (data-area side), on each side.
DEFAULT_QUIET_ZONE_RATIO = QUIET_ZONE


def default_quiet_zone(tag_size: float) -> float:
    """Default quiet-zone width (each side) for a data area of side ``tag_size``.

    Parameters
    ----------
    tag_size : float
        Side of the data area (any length unit).

    Returns
    -------
    float
        ``DEFAULT_QUIET_ZONE_RATIO × tag_size`` (0.25 × size), same unit.
    """
    return DEFAULT_QUIET_ZONE_RATIO * tag_size


@dataclass(frozen=True)
class TagGeometry:
    """Everything needed to draw one tag, independent of the output medium.

    - ``points``: the k points in data-area unit coordinates (x right, y down, origin the
      top-left corner of the data area, which is [0, 1]²);
    - ``triangles``: index triples into ``points`` (the layout);
    - ``polarity``: ``"normal"`` = white quiet zone, black data area, white triangles;
      ``"inverted"`` = black quiet zone, white data area, black triangles;
    - ``tag_size``: side of the data area (the square users measure), mm for vector output;
    - ``quiet_zone``: width of the quiet zone on each side of the data area, same unit;
    - ``mp_unit``: MP of ``points`` in data-area units (printed MP = ``mp_unit · tag_size``);
    - ``transform``: the ``(2, 3)`` affine map from the source (file) coordinates to ``points``.
    """

    points: tuple[tuple[float, float], ...]
    triangles: tuple[tuple[int, int, int], ...]
    polarity: Polarity
    tag_size: float
    quiet_zone: float
    mp_unit: float
    transform: tuple[tuple[float, float, float], tuple[float, float, float]]

    @property
    def k(self) -> int:
        """Number of points."""
        return len(self.points)

    @property
    def mp_mm(self) -> float:
        """Printed MP in the unit of ``tag_size`` (mm for vector output)."""
        return self.mp_unit * self.tag_size

    @property
    def total_size(self) -> float:
        """Side of the whole tag, quiet zone included: ``tag_size + 2 · quiet_zone``."""
        return self.tag_size + 2.0 * self.quiet_zone

    @property
    def inverted(self) -> bool:
        """True for the inverted polarity."""
        return self.polarity == "inverted"

    @property
    def points_array(self) -> NDArray[np.float64]:
        """``(k, 2)`` float64 copy of ``points`` (unit coordinates)."""
        return np.array(self.points, dtype=np.float64).reshape(-1, 2)

    def resized(self, tag_size: float, quiet_zone: float | None = None) -> TagGeometry:
        """The same tag with another data-area side (and quiet zone, default 0.25 × size)."""
        q = default_quiet_zone(tag_size) if quiet_zone is None else quiet_zone
        _check_sizes(tag_size, q)
        return dataclasses.replace(self, tag_size=float(tag_size), quiet_zone=float(q))

    def with_polarity(self, polarity: Polarity) -> TagGeometry:
        """The same tag in the other (or same) polarity."""
        _check_polarity(polarity)
        return dataclasses.replace(self, polarity=polarity)

    def tones(self) -> tuple[int, int, int]:
        """Grey levels (0 black, 255 white) of quiet zone, data area and triangles."""
        return (0, 255, 0) if self.inverted else (255, 0, 255)


def _check_polarity(polarity: str) -> None:
    if polarity not in POLARITIES:
        raise UsageError(f"polarity must be 'normal' or 'inverted', got {polarity!r}")


def _check_sizes(tag_size: float, quiet_zone: float) -> None:
    if not np.isfinite(tag_size) or tag_size <= 0:
        raise UsageError(f"tag size must be positive, got {tag_size}")
    if not np.isfinite(quiet_zone) or quiet_zone < 0:
        raise UsageError(f"quiet zone must be zero or positive, got {quiet_zone}")


def build_tag_geometries(
    points_batch: ArrayLike,
    triangles_batch: Sequence[Sequence[Sequence[int]]],
    *,
    polarity: Polarity = "normal",
    tag_size: float = 50.0,
    quiet_zone: float | None = None,
    inner_margin: float = DEFAULT_INNER_MARGIN,
    placements: ArrayLike | None = None,
) -> list[TagGeometry]:
    """Tag geometries of ``B`` point sets and their layouts.

    Parameters
    ----------
    points_batch : array_like
        ``(B, k, 2)`` point sets in file coordinates.
    triangles_batch : sequence
        Per set, its layout: index triples into the set's points.
    polarity : {"normal", "inverted"}
        Tones of the tags.
    tag_size : float
        Side of the data area (mm for vector output).
    quiet_zone : float, optional
        Quiet-zone width on each side, same unit; default :func:`default_quiet_zone`.
    inner_margin : float
        Smallest point-to-border distance in data-area units, when placing afresh.
    placements : array_like, optional
        ``(B, 2, 3)`` affine maps from file coordinates to data-area units, e.g. the ones
        stored with the layouts; None places the sets with
        :func:`ottag_db.core.placement.tag_placements` (batched, using ``inner_margin``).

    Returns
    -------
    list of TagGeometry
        One per set, in order; ``mp_unit`` is the MP of the placed points.

    Raises
    ------
    UsageError
        Bad polarity or sizes.
    ExportError
        A layout that does not fit its set.
    """
    _check_polarity(polarity)
    q = default_quiet_zone(tag_size) if quiet_zone is None else quiet_zone
    _check_sizes(tag_size, q)
    pts, _ = as_point_batch(points_batch)
    if len(triangles_batch) != pts.shape[0]:
        raise ValueError(f"{pts.shape[0]} point sets but {len(triangles_batch)} layouts")
    if placements is None:
        maps = tag_placements(pts, inner_margin)
    else:
        maps = np.asarray(placements, dtype=np.float64)
        if maps.shape != (pts.shape[0], 2, 3):
            raise ValueError(f"{pts.shape[0]} point sets need placements of shape (B, 2, 3), got {maps.shape}")
    placed = apply_placements(maps, pts)
    mps = maximal_perturbations(placed)
    k = pts.shape[1]
    out: list[TagGeometry] = []
    for n in range(pts.shape[0]):
        tris = tuple(tuple(sorted(int(i) for i in t)) for t in triangles_batch[n])
        if not tris or any(len(t) != 3 or not all(0 <= i < k for i in t) for t in tris):
            raise ExportError(f"set {n}: layout {triangles_batch[n]!r} does not fit {k} points")
        out.append(
            TagGeometry(
                points=tuple((float(px), float(py)) for px, py in placed[n]),
                triangles=tris,  # type: ignore[arg-type]
                polarity=polarity,
                tag_size=float(tag_size),
                quiet_zone=float(q),
                mp_unit=float(mps[n]),
                transform=(
                    (float(maps[n, 0, 0]), float(maps[n, 0, 1]), float(maps[n, 0, 2])),
                    (float(maps[n, 1, 0]), float(maps[n, 1, 1]), float(maps[n, 1, 2])),
                ),
            )
        )
    return out


def build_tag_geometry(
    points: ArrayLike,
    triangles: Sequence[Sequence[int]],
    *,
    polarity: Polarity = "normal",
    tag_size: float = 50.0,
    quiet_zone: float | None = None,
    inner_margin: float = DEFAULT_INNER_MARGIN,
) -> TagGeometry:
    """Tag geometry of one point set, placed afresh; see :func:`build_tag_geometries`.

    Parameters
    ----------
    points : array_like
        ``(k, 2)`` points in file coordinates.
    triangles : sequence of sequence of int
        The layout: index triples into ``points``.
    polarity, tag_size, quiet_zone, inner_margin
        As in :func:`build_tag_geometries`.

    Returns
    -------
    TagGeometry
        The placed tag.
    """
    arr = np.asarray(points)
    if arr.ndim != 2:
        raise ValueError(f"build_tag_geometry takes one point set of shape (k, 2), got {arr.shape}")
    return build_tag_geometries(
        arr[None],
        [triangles],
        polarity=polarity,
        tag_size=tag_size,
        quiet_zone=quiet_zone,
        inner_margin=inner_margin,
    )[0]
