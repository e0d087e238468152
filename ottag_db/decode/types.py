"""The decoder's data: results (:class:`Detection`, :class:`Rejected`) and the values between stages.

Data flow of one frame (each arrow a stage module of :mod:`ottag_db.decode`)::

    image ─image→ grey ─candidates→ Quad ─segmentation→ DataArea ─segmentation→ Decomposition
      ─refine→ TriangleLines ─cluster→ PointHypothesis ─identify/verify→ Detection | Rejection

A stage that cannot go on returns a :class:`Rejection` (a :data:`RejectReason` with a detail);
the detector turns it into a :class:`Rejected` with the candidate's quad.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from numpy.typing import NDArray

from ottag_db.core.types import Polarity

__all__ = [
    "REJECTION_REASONS",
    "STAGES",
    "DataArea",
    "Decomposition",
    "Detection",
    "DetectionReport",
    "ModelGuess",
    "PointHypothesis",
    "Quad",
    "RejectReason",
    "Rejected",
    "Rejection",
    "StageName",
    "TriangleLines",
]

_F64 = NDArray[np.float64]

#: Why a candidate data area did not become a detection (``Rejected.reason``; the values
#: appear in ``decode --json``).
RejectReason = Literal[
    "low_contrast",
    "no_triangles",
    "touches_border",
    "non_triangle",
    "point_count",
    "general_position",
    "low_margin",
    "unknown_id",
    "verification",
    "quad_inconsistent",
    "polarity_not_in_dictionary",
]

#: Each :data:`RejectReason` with its meaning.
REJECTION_REASONS: dict[RejectReason, str] = {
    "low_contrast": "the data area holds no two clearly separated grey levels",
    "no_triangles": "no triangle was found inside the data area",
    "touches_border": "a component inside the data area touches its border",
    "non_triangle": "a component inside the data area is not a union of triangles",
    "point_count": "the number of points is outside 3…9 or not held by the lookup",
    "general_position": "three detected points are (numerically) collinear",
    "low_margin": "the smallest point-to-line distance is below min_margin_px",
    "unknown_id": "the order type is not in the lookup",
    "verification": "no stored realization maps onto the points within the reprojection bound",
    "quad_inconsistent": "the data-area corners do not map to a parallelogram of the tag plane",
    "polarity_not_in_dictionary": "the order type is a dictionary member, but not in the detected polarity",
}

#: The stages timed by :meth:`ottag_db.decode.Detector.detect_with_report`, in pipeline order.
StageName = Literal[
    "image", "candidates", "segmentation", "triangles", "refine", "cluster",
    "identify", "verify", "upsample", "rectify", "model",
]  # fmt: skip
STAGES: tuple[StageName, ...] = get_args(StageName)


@dataclass(frozen=True)
class Detection:
    """One decoded Order Type Tag in an image.

    Image coordinates are pixels, x = column, y = row, origin at the *centre* of the top-left
    pixel (OpenCV's convention), sub-pixel floats.

    - ``lambda_text``: canonical ID ``k:digits``; ``k`` the number of points;
    - ``order_type_id`` / ``tag``: from the lookup entry (None for unknown order types,
      reported only with ``allow_unknown=True``); when the entry's ``extra["tags"]`` maps
      polarity → number (a dictionary lookup), ``tag`` is the number of the detected polarity;
    - ``polarity``: ``"normal"`` (white triangles on a black data area) or ``"inverted"``;
    - ``points``: ``(k, 2)`` detected points, row ``l`` = the point with canonical label ``l``;
    - ``model_points``: ``(k, 2)`` the matched stored realization in canonical order (file/grid
      coordinates), only when the order type has a unique minimal ordering, else None;
    - ``corners``: ``(4, 2)`` sub-pixel data-area corners in the order tag top-left, top-right,
      bottom-right, bottom-left (tag plane, x right, y down), found by mapping the corners
      back through ``homography``; without a homography they are in image clockwise order
      starting at the corner nearest the image origin;
    - ``homography``: ``(3, 3)`` map from the realization's file coordinates (tag plane) to
      the image, normalised so ``H[2, 2] = 1``; None when no realization was available;
    - ``reprojection_error_px``: largest distance between a detected point and its
      realization point mapped by ``homography`` (None without a homography);
    - ``margin_px``: smallest distance from a detected point to a line through two others;
    - ``corrected_flips``: None for a reading with ``margin_px >= min_margin_px``; for a
      soft-decoded one (margin below it, see :mod:`ottag_db.decode.soft`) the number of its
      near-collinear triples whose orientation was reversed to reach the ID (0: the reading
      as measured, confirmed against every reversal);
    - ``model_correlation``: None for a reading of measured points; for a tag read by model
      at a grazing view (:mod:`ottag_db.decode.model_match`: the stored tags projected through
      the quad, the best aligned to the image) the correlation of the aligned tag with the
      image. Its ``points`` are then the stored realization mapped by ``homography`` (not
      measured one by one), and ``reprojection_error_px`` is None;
    - ``corners_seen``: per corner of ``corners``, whether it was seen where the tag's printed
      placement puts it; a corner that was not (hidden, outside the frame) is given at its
      printed position, from the points (:func:`~ottag_db.decode.placement_check.printed_corners`).
      None when the placement is unknown (a dictionary file) or for a reading by model;
      ``corners_measured``: when one takes its printed position, all 4 as measured, in file coordinates.
    """

    lambda_text: str
    k: int
    order_type_id: int | None
    tag: int | None
    polarity: Polarity
    points: _F64
    model_points: _F64 | None
    corners: _F64
    homography: _F64 | None
    reprojection_error_px: float | None
    margin_px: float
    corrected_flips: int | None = None
    model_correlation: float | None = None
    corners_seen: tuple[bool, ...] | None = None
    corners_measured: _F64 | None = None

    @property
    def center(self) -> tuple[float, float]:
        """Centre of the data area (mean of the corners), image pixels."""
        c = self.corners.mean(axis=0)
        return float(c[0]), float(c[1])


@dataclass(frozen=True)
class Rejected:
    """A candidate data area that did not become a detection.

    ``reason`` is a :data:`RejectReason` (a key of :data:`REJECTION_REASONS`); ``corners`` the
    ``(4, 2)`` candidate quad (image pixels, clockwise on screen); ``lambda_text`` the ID read
    before the rejection, if any; ``detail`` a short readable explanation with the measured value.
    """

    reason: RejectReason
    polarity: Polarity
    corners: _F64
    lambda_text: str | None = None
    detail: str = ""


@dataclass(frozen=True)
class DetectionReport:
    """Everything one :meth:`~ottag_db.decode.Detector.detect_with_report` call found.

    ``timings`` holds ``(stage, seconds)`` for every stage of :data:`STAGES`, in that order
    (wall time spent in the stage over all candidates of the frame); ``passes`` holds
    ``(pass, seconds)`` for each candidate pass that ran (a binarization of
    :func:`~ottag_db.decode.candidates.find_quads`: ``"adaptive"``, ``"otsu"``, …), in order,
    from its start to the next one's, its readings included: a frame that reads nothing in the
    first pass runs the later ones too.
    """

    detections: list[Detection]
    rejected: list[Rejected]
    timings: tuple[tuple[StageName, float], ...]
    passes: tuple[tuple[str, float], ...] = ()


# ---------------------------------------------------------------------- between the stages
@dataclass(frozen=True)
class Quad:
    """A candidate data area: ``corners`` ``(4, 2)`` clockwise on screen (image pixels,
    starting nearest the image origin), its ``area`` (px²) and the ``polarity`` it was found in;
    ``inferred``: its outline was no quad (partly hidden, or cut by the frame's edge) and the
    corners were inferred from the visible sides, so a reading must show the tag as printed —
    unless ``frame_cut``: only the frame's edge hides a sliver of its border, no triangle
    (:func:`~ottag_db.decode.outlines.cut_by_frame_only`), and its points decide."""

    polarity: Polarity
    corners: _F64
    area: float
    inferred: bool = False
    frame_cut: bool = False


@dataclass(frozen=True)
class ModelGuess:
    """The tag a reading by model aligned best to a candidate it refused: ``lambda_text``,
    ``polarity`` and the ``correlation`` of the aligned tag with the frame."""

    lambda_text: str
    polarity: Polarity
    correlation: float


@dataclass(frozen=True)
class Rejection:
    """Why a stage stopped reading a candidate (converted to :class:`Rejected` by the detector).

    ``decomposed`` is False when no triangle decomposition of the data area was found at all
    (the detector then does not retry the candidate upsampled). ``not_printed`` holds the IDs
    a reading of the data area was refused as because the detected triangles or points are not
    that tag as printed (its stored layout or placement): the data area's other readings of
    those IDs (other decompositions, the upsampled and rectified views) must then show them as
    printed too (:func:`~ottag_db.decode.reading.read_area`). ``model_best`` is the tag a
    reading by model aligned best when it refused the candidate (its ID, polarity and
    correlation): a reading by model of the same data area from another outline must beat it by
    ``model_min_gap`` unless it reads that tag (:func:`~ottag_db.decode.model_match.read_model`).
    """

    reason: RejectReason
    detail: str = ""
    lambda_text: str | None = None
    decomposed: bool = True
    not_printed: frozenset[str] = frozenset()
    model_best: ModelGuess | None = None

    def at(self, quad: Quad) -> Rejected:
        """The public :class:`Rejected` of this rejection for the candidate ``quad``."""
        return Rejected(self.reason, quad.polarity, quad.corners.copy(), self.lambda_text, self.detail)


@dataclass(frozen=True)
class DataArea:
    """The segmented data area of one candidate, in ROI coordinates.

    - ``roi``: the grey image around the quad (inverted for inverted tags: triangles bright);
    - ``origin``: image position ``(x, y)`` of ROI pixel ``(0, 0)``;
    - ``quad``: ``(4, 2)`` the candidate corners in ROI coordinates; ``side``: √area (px);
    - ``level``: grey level halfway between the dark and the bright class;
    - ``fg``: uint8 mask (255 = bright) of the triangles inside the interior of the quad;
    - ``intrusions``: bright components left out of ``fg`` because they cross the quad's
      border (a finger or bar across the tag; no printed triangle comes near the border): a
      reading of such a data area must show the tag as printed, layout and placement.
    """

    roi: NDArray[np.uint8]
    origin: _F64
    quad: _F64
    side: float
    level: float
    fg: NDArray[np.uint8]
    intrusions: int = 0


@dataclass(frozen=True)
class Decomposition:
    """Triangles found in one data area: three contour side chains per triangle, each an
    ``(m, 2)`` float64 array of ROI pixel positions (side j runs from vertex j to j+1)."""

    chains: tuple[_F64, ...]

    @property
    def count(self) -> int:
        """Number of triangles."""
        return len(self.chains) // 3


@dataclass(frozen=True)
class TriangleLines:
    """Refined triangle sides: ``normal`` ``(S, 2)`` unit normals and ``offset`` ``(S,)`` with
    n·x = c (ROI pixels; sides 3t, 3t+1, 3t+2 of triangle t), and ``vertices`` ``(T, 3, 2)``
    (vertex j = side j−1 ∩ side j)."""

    normal: _F64
    offset: _F64
    vertices: _F64


@dataclass(frozen=True)
class PointHypothesis:
    """One reading of the triangle vertices as points: ``points`` ``(k, 2)`` and, for each
    point, the indices ``line_ids[i]`` of the triangle side lines through it."""

    points: _F64
    line_ids: tuple[NDArray[np.int64], ...]
