"""PoseTracker (ottag_db.app.pose_tracking): an ambiguous pose chosen by the previous frames,
on real poses from estimate_pose (synthetic far tags, real OpenCV) and on decode's JSON."""

from __future__ import annotations

import copy
import dataclasses
import json
import math

import numpy as np
import pytest

from ottag_db.app.decoding import Camera, detection_json
from ottag_db.app.pose_tracking import PoseTracker, pose_ambiguity_json
from ottag_db.decode.pose import Pose
from ottag_db.errors import UsageError
from tests.decode.test_pose_ambiguity import K, _detection, _normal_error, _pose, _true_pose


@pytest.fixture(scope="module")
def ambiguous() -> tuple[Pose, np.ndarray]:
    """A far, small tag whose frame cannot choose between the two mirrored poses, and its true R."""
    rng = np.random.default_rng(11)
    for _ in range(400):
        r_mat, t = _true_pose(rng.uniform(2.2, 2.5), rng.uniform(15, 25), rng.uniform(0, 2 * math.pi), 0.0)
        pose = _pose(_detection(r_mat, t, rng))
        if pose.ambiguous:
            return pose, r_mat
    raise AssertionError("no ambiguous pose among 400 far tags")


def test_an_ambiguous_frame_follows_the_track(ambiguous: tuple[Pose, np.ndarray]) -> None:
    pose, _ = ambiguous
    mirror = pose.swapped()
    tracker = PoseTracker()
    # the track starts at a pose its frame chose clearly, on the mirror's side
    first = tracker.choose("tag", 0, dataclasses.replace(mirror, ambiguous=False, ambiguity=0.0))
    assert first.chosen_by == "frame"
    got = tracker.choose("tag", 1, pose)
    assert got.chosen_by == "previous_frames"
    assert np.allclose(got.pose.R, mirror.R) and np.allclose(got.pose.alternative.rvec, pose.rvec)
    # the track follows the reported pose: the next ambiguous frame stays on that side
    assert tracker.choose("tag", 2, pose).chosen_by == "previous_frames"
    # another tag has its own track (none yet): its frame's choice
    assert tracker.choose("other", 2, pose).chosen_by == "frame"


def test_no_track_no_choice_and_gaps_end_tracks(ambiguous: tuple[Pose, np.ndarray]) -> None:
    pose, _ = ambiguous
    tracker = PoseTracker(max_gap_frames=5)
    # an ambiguous pose of an untracked tag starts nothing
    assert tracker.choose("tag", 0, pose).chosen_by == "frame"
    assert tracker.tracks == {}
    tracker.choose("tag", 1, dataclasses.replace(pose.swapped(), ambiguous=False))
    assert tracker.choose("tag", 7, pose).chosen_by == "frame"  # 6 frames later: too old
    # an unambiguous pose is never overruled
    tracker.choose("tag", 8, dataclasses.replace(pose.swapped(), ambiguous=False))
    clear = dataclasses.replace(pose, ambiguous=False)
    assert tracker.choose("tag", 9, clear).pose is clear
    with pytest.raises(UsageError):
        PoseTracker(max_gap_frames=0)


def test_a_far_sequence_keeps_the_true_side() -> None:
    """A tag seen clearly, then far away: every ambiguous frame is reported within 10° of the truth."""
    rng = np.random.default_rng(3)
    tracker = PoseTracker()
    r_mat, t = _true_pose(0.8, 20.0, 0.4, 0.0)
    start = tracker.choose("tag", 0, _pose(_detection(r_mat, t, rng)))
    assert not start.pose.ambiguous and _normal_error(start.pose.R, r_mat) < 3
    r_far, t_far = _true_pose(2.4, 20.0, 0.4, 0.0)  # the same tilt, farther: ambiguous now and then
    n_ambiguous = 0
    for frame in range(1, 60):
        pose = _pose(_detection(r_far, t_far, rng))
        got = tracker.choose("tag", frame, pose)
        n_ambiguous += pose.ambiguous
        assert _normal_error(got.pose.R, r_far) < 10 or not pose.ambiguous
    assert n_ambiguous >= 1


def test_json_keys_and_the_record_tracker(ambiguous: tuple[Pose, np.ndarray]) -> None:
    pose, _ = ambiguous
    keys = pose_ambiguity_json(pose)
    assert set(keys) == {"ambiguity", "ambiguous", "alternative", "alternative_angle_deg", "chosen_by"}
    assert keys["ambiguous"] is True and keys["chosen_by"] == "frame" and 0 < keys["ambiguity"] <= 1
    d = _detection(*_true_pose(2.4, 20.0, 0.4, 0.0), np.random.default_rng(1))
    out = detection_json(d, camera=Camera(K, np.zeros(5)), tag_size=100.0)
    for key in ("ambiguity", "ambiguous", "alternative", "alternative_angle_deg", "chosen_by"):
        assert key in out["pose"]
    assert {"rvec", "tvec", "reprojection_error_px"} <= set(out["pose"]["alternative"])
    json.dumps(out)
    # a record tracker swaps the pose of an ambiguous frame to the side of the track
    rec = {"detections": [{"lambda": "8:x", "polarity": "normal", "tag": None, "pose": {}}]}
    mirror = pose.swapped()
    p0 = rec["detections"][0]["pose"]
    p0.update(rvec=mirror.rvec.tolist(), tvec=mirror.tvec.tolist(), R=mirror.R.tolist(), reprojection_error_px=0.1)
    p0.update(pose_ambiguity_json(dataclasses.replace(mirror, ambiguous=False)))
    tracker = PoseTracker()
    tracker.track_record(0, rec)
    assert p0["chosen_by"] == "frame"
    rec2 = copy.deepcopy(rec)
    p1 = rec2["detections"][0]["pose"]
    p1.update(rvec=pose.rvec.tolist(), tvec=pose.tvec.tolist(), R=pose.R.tolist(), reprojection_error_px=0.2)
    p1.update(pose_ambiguity_json(pose))
    tracker.track_record(1, rec2)
    assert p1["chosen_by"] == "previous_frames"
    assert np.allclose(p1["R"], mirror.R, atol=1e-9) and np.allclose(p1["alternative"]["rvec"], pose.rvec)
