"""Poses that stay put on video: the planar ambiguity of one frame resolved by the frames before it.

A tag seen nearly head-on, small and far, fits two mirrored poses almost equally; when its frame
alone cannot choose (:attr:`ottag_db.decode.pose.Pose.ambiguous`), a :class:`PoseTracker` takes
the one whose tag normal is closer to the tag's last reported normal. The detector stays
stateless: the tracker is a separate object the caller keeps for one video (``decode`` keeps
one per video file) and feeds frame by frame, in order.

JSON (``decode --json`` with ``--camera`` and ``--tag-size``; keys added to ``"pose"``):

- ``"ambiguity"``: likelihood of the mirrored pose relative to the reported one, in [0, 1];
- ``"ambiguous"``: true when the frame alone cannot choose between them;
- ``"alternative"``: the mirrored pose (``rvec``, ``tvec``, ``reprojection_error_px``);
- ``"alternative_angle_deg"``: angle between the two poses' tag normals;
- ``"chosen_by"``: ``"frame"`` (the frame's own choice) or ``"previous_frames"`` (an ambiguous
  frame whose pose a video's earlier frames chose; the frame's own choice is then
  ``"alternative"``).
"""

from __future__ import annotations

import math
from collections.abc import Hashable
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from ottag_db.decode.pose import Pose
from ottag_db.errors import UsageError

__all__ = ["MAX_GAP_FRAMES", "ChosenBy", "PoseTracker", "TrackedPose", "pose_ambiguity_json"]

_F64 = NDArray[np.float64]

#: How a reported pose was chosen: by its frame alone, or (ambiguous frame) by the frames before.
ChosenBy = Literal["frame", "previous_frames"]

#: A tag's last pose chooses for an ambiguous frame only when it is at most this many frames
#: old (frame indices; 0.6 s at 25 fps). In that time a tag turns relative to a hand-held or
#: vehicle camera by a few degrees, well under the
#: :data:`~ottag_db.decode.pose.AMBIGUITY_MIN_ANGLE_DEG` (10°) that
#: at least separate two poses the tracker chooses between; after a longer gap the last pose no
#: longer tells them apart and the frame's own choice is reported.
MAX_GAP_FRAMES = 15


@dataclass(frozen=True)
class TrackedPose:
    """A pose as reported on video: ``pose`` (the frame's, or its :meth:`~Pose.swapped` one when
    the previous frames chose the alternative) and ``chosen_by``."""

    pose: Pose
    chosen_by: ChosenBy


def _normal(rvec: Any) -> _F64:
    """The tag normal (third column of R) of a Rodrigues vector, camera frame."""
    r_mat, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3))
    return np.asarray(r_mat, dtype=np.float64)[:, 2]


def _angle_deg(a: _F64, b: _F64) -> float:
    return math.degrees(math.acos(float(np.clip(a @ b, -1.0, 1.0))))


class PoseTracker:
    """Chooses, for each tag in an ambiguous frame, the mirrored pose consistent with its track.

    State (the only state, visible as :attr:`tracks`): per tag key, the frame index and tag
    normal of its last reported pose. A track starts at a pose its frame chose unambiguously
    (an ambiguous pose of an untracked tag is reported as its frame chose it and starts nothing:
    it could start the track on the wrong side). While a track lasts (the tag seen again within
    ``max_gap_frames``), each pose of the tag updates it, and an ambiguous one is replaced by
    its alternative when the alternative's normal is closer to the track's.

    Parameters
    ----------
    max_gap_frames : int
        Longest gap (frame indices) over which a track still chooses (≥ 1, default
        :data:`MAX_GAP_FRAMES`).
    """

    def __init__(self, max_gap_frames: int = MAX_GAP_FRAMES) -> None:
        if max_gap_frames < 1:
            raise UsageError(f"max_gap_frames must be at least 1, got {max_gap_frames}")
        self.max_gap_frames = max_gap_frames
        self.tracks: dict[Hashable, tuple[int, _F64]] = {}

    def _use_alternative(self, key: Hashable, frame: int, normal: _F64, alt: _F64, ambiguous: bool) -> bool:
        """Whether the track of ``key`` takes the alternative at ``frame``; updates the track."""
        last = self.tracks.get(key)
        live = last is not None and 0 <= frame - last[0] <= self.max_gap_frames
        use_alt = ambiguous and last is not None and live and _angle_deg(alt, last[1]) < _angle_deg(normal, last[1])
        if live or not ambiguous:
            self.tracks[key] = (frame, alt if use_alt else normal)
        return use_alt

    def choose(self, key: Hashable, frame: int, pose: Pose) -> TrackedPose:
        """The pose to report for tag ``key`` in frame ``frame``.

        Parameters
        ----------
        key : hashable
            Identifies one physical tag across frames (e.g. its ID and polarity).
        frame : int
            Frame index; frames come in increasing order.
        pose : Pose
            The frame's pose of the tag (:func:`~ottag_db.decode.estimate_pose`).

        Returns
        -------
        TrackedPose
            ``pose`` itself (``"frame"``) or its swapped form (``"previous_frames"``).
        """
        if self._use_alternative(key, frame, pose.R[:, 2], _normal(pose.alternative.rvec), pose.ambiguous):
            return TrackedPose(pose.swapped(), "previous_frames")
        return TrackedPose(pose, "frame")

    def track_record(self, frame: int, fields: dict[str, Any]) -> None:
        """Apply :meth:`choose` to the JSON detections of one frame, in place.

        Parameters
        ----------
        frame : int
            Frame index.
        fields : dict
            The frame's ``{"detections": [...]}`` from
            :func:`ottag_db.app.decoding.decode_array`; detections with a ``"pose"`` (and its
            ``"alternative"``) are tracked by ``(lambda, polarity, tag)``, unless that key
            occurs twice in the frame (two such tags cannot be told apart: frame's choice).
        """
        dets = [d for d in fields.get("detections", []) if "alternative" in (d.get("pose") or {})]
        keys = [(d["lambda"], d["polarity"], d["tag"]) for d in dets]
        for d, key in zip(dets, keys, strict=True):
            if keys.count(key) > 1:
                continue
            p = d["pose"]
            normal = np.asarray(p["R"], dtype=np.float64)[:, 2]
            if self._use_alternative(key, frame, normal, _normal(p["alternative"]["rvec"]), bool(p["ambiguous"])):
                alt = p["alternative"]
                p["alternative"] = {k: p[k] for k in ("rvec", "tvec", "reprojection_error_px")}
                r_mat, _ = cv2.Rodrigues(np.asarray(alt["rvec"], dtype=np.float64))
                p.update(rvec=alt["rvec"], tvec=alt["tvec"], R=np.asarray(r_mat).tolist())
                p.update(reprojection_error_px=alt["reprojection_error_px"], chosen_by="previous_frames")


def pose_ambiguity_json(pose: Pose) -> dict[str, Any]:
    """The ambiguity keys of a pose's JSON object (see the module docstring).

    Parameters
    ----------
    pose : Pose
        A pose from :func:`~ottag_db.decode.estimate_pose`.

    Returns
    -------
    dict
        ``ambiguity``, ``ambiguous``, ``alternative``, ``alternative_angle_deg`` and
        ``chosen_by`` (``"frame"``; a :class:`PoseTracker` may change it on video).
    """
    alt = pose.alternative
    return {
        "ambiguity": round(pose.ambiguity, 6),
        "ambiguous": pose.ambiguous,
        "alternative": {
            "rvec": np.asarray(alt.rvec).ravel().tolist(),
            "tvec": np.asarray(alt.tvec).ravel().tolist(),
            "reprojection_error_px": alt.reprojection_error_px,
        },
        "alternative_angle_deg": round(pose.alternative_angle_deg, 3),
        "chosen_by": "frame",
    }
