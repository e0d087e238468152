"""Decoding: image → Order Type Tag detections, as a pipeline of stages (see :mod:`.detector`).

Imports only :mod:`ottag_db.core` (and :mod:`ottag_db.errors`); a detector is built from any
:class:`~ottag_db.core.lookup.TagLookup` (``ottag_db.app.detector`` builds one from a database).
"""

from __future__ import annotations

from ottag_db.decode.detector import DEFAULT_PARAMS, Detector
from ottag_db.decode.image import to_gray
from ottag_db.decode.params import DetectorParams
from ottag_db.decode.pose import Pose, PoseSolution, estimate_pose, placement_from_detection, tag_object_points
from ottag_db.decode.types import (
    REJECTION_REASONS,
    STAGES,
    Detection,
    DetectionReport,
    Rejected,
    RejectReason,
    StageName,
)

__all__ = [
    "DEFAULT_PARAMS",
    "REJECTION_REASONS",
    "STAGES",
    "Detection",
    "DetectionReport",
    "Detector",
    "DetectorParams",
    "Pose",
    "PoseSolution",
    "RejectReason",
    "Rejected",
    "StageName",
    "estimate_pose",
    "placement_from_detection",
    "tag_object_points",
    "to_gray",
]
