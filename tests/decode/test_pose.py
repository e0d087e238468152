"""Pose from decoded Order Type Tags on synthetic renders, compared with an ArUco marker."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from ottag_db.core.geometry import maximal_perturbation
from ottag_db.decode import Detector, estimate_pose, placement_from_detection
from ottag_db.errors import UsageError
from ottag_db.printing import scenes as sc
from tests.support.tagsynth import scene_data

SIZE = 0.1  # data-area side, metres


def _rot_err_deg(r1: np.ndarray, r2: np.ndarray) -> float:
    c = (np.trace(r1 @ r2.T) - 1) / 2
    return math.degrees(math.acos(float(np.clip(c, -1, 1))))


@pytest.fixture(scope="module")
def setup(bundled_db_path):
    lookup, tags = scene_data(bundled_db_path)
    good = [t for t in tags if t.k >= 7 and maximal_perturbation(t.points) >= 6.0]
    return lookup, good


def _poses(n: int, seed: int):
    rng = np.random.default_rng(seed)
    k_mat = sc.camera_matrix()
    for _ in range(n):
        width = rng.uniform(120, 220)
        tilt = rng.uniform(0, 60)
        r_mat, t = sc.random_pose(rng, k_mat, SIZE, width, tilt, (320 + rng.uniform(-40, 40), 240))
        yield rng, k_mat, r_mat, t


def test_pose_accuracy_vs_aruco(setup, capsys):
    lookup, good = setup
    det = Detector(lookup)
    aruco = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250), cv2.aruco.DetectorParameters()
    )
    marker = cv2.aruco.generateImageMarker(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250), 3, 400)
    marker = cv2.copyMakeBorder(marker, 100, 100, 100, 100, cv2.BORDER_CONSTANT, value=255)
    ours_r, ours_t, aru_r, aru_t = [], [], [], []
    for i, (rng, k_mat, r_mat, t) in enumerate(_poses(12, 7)):
        rec = good[int(rng.integers(len(good)))]
        hom = sc.pose_homography(k_mat, r_mat, t, SIZE)
        pol = "normal" if i % 2 == 0 else "inverted"
        spec = sc.TagSpec(rec.points, rec.triangles, hom, pol, placement=rec.placement)
        scene = sc.render_scene((480, 640), [spec], rng, blur=0.6, noise=2.0)
        found = [d for d in det.detect(scene.image) if d.lambda_text == rec.lambda_text]
        assert found, f"pose scene {i}: tag not decoded"
        pose = estimate_pose(found[0], k_mat, None, SIZE, rec.placement)
        ours_r.append(_rot_err_deg(pose.R, r_mat))
        ours_t.append(float(np.linalg.norm(pose.tvec - t) / np.linalg.norm(t)))
        assert len(pose.solutions) >= 1 and pose.reprojection_error_px < 1.0
        if found[0].model_points is not None:
            assert pose.n_points == 4 + found[0].k
        # estimated placement gives the same pose within tolerance
        est = estimate_pose(found[0], k_mat, None, SIZE)
        assert _rot_err_deg(est.R, r_mat) < 2.0
        # the same pose with an ArUco marker of the same size (patch = marker incl. white margin)
        hom_m = hom @ np.array([[1.5, 0, -0.25], [0, 1.5, -0.25], [0, 0, 1.0]])
        aru_scene = sc.render_scene((480, 640), [], rng, blur=0.6, noise=2.0, extra=[(marker, hom_m)])
        corners, ids, _ = aruco.detectMarkers(aru_scene.image)
        assert ids is not None and len(ids) == 1
        h = SIZE / 2
        obj = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], dtype=np.float64)
        ok, rvec, tvec = cv2.solvePnP(obj, corners[0].reshape(4, 2), k_mat, None, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        assert ok
        r_a, _ = cv2.Rodrigues(rvec)
        # ArUco frame: centre origin, y up, z out of the marker → ours: corner origin, y down, z in
        r_ours = r_a @ np.diag([1.0, -1.0, -1.0])
        t_ours = tvec.ravel() - r_ours @ np.array([h, h, 0])
        aru_r.append(_rot_err_deg(r_ours, r_mat))
        aru_t.append(float(np.linalg.norm(t_ours - t) / np.linalg.norm(t)))
    with capsys.disabled():
        print(
            f"\npose (12 renders, 120–220 px, tilt ≤ 60°): rotation error mean/max "
            f"ours {np.mean(ours_r):.3f}/{np.max(ours_r):.3f}° ArUco {np.mean(aru_r):.3f}/{np.max(aru_r):.3f}°; "
            f"translation error mean/max ours {100 * np.mean(ours_t):.3f}/{100 * np.max(ours_t):.3f} % "
            f"ArUco {100 * np.mean(aru_t):.3f}/{100 * np.max(aru_t):.3f} %"
        )
    assert max(ours_r) < 1.0
    assert max(ours_t) < 0.01
    # issue 13's pose target, in-suite: mean normal error ≤ 0.8 × ArUco's, max no worse
    assert np.mean(ours_r) <= 0.8 * np.mean(aru_r)
    assert max(ours_r) <= max(aru_r)


def test_corner_weighting_and_refinement(setup):
    """The weighted refinement moves the pose off the plain least-squares one and not away from
    the truth; every setting reproduces the image within a pixel and keeps both IPPE solutions."""
    lookup, good = setup
    det = Detector(lookup)
    plain, weighted = [], []
    for i, (rng, k_mat, r_mat, t) in enumerate(_poses(6, 11)):
        rec = good[(3 * i) % len(good)]
        spec = sc.TagSpec(rec.points, rec.triangles, sc.pose_homography(k_mat, r_mat, t, SIZE), placement=rec.placement)
        scene = sc.render_scene((480, 640), [spec], rng, blur=0.6, noise=2.0)
        found = [d for d in det.detect(scene.image) if d.lambda_text == rec.lambda_text]
        assert found, f"scene {i}: tag not decoded"
        p0 = estimate_pose(found[0], k_mat, None, SIZE, rec.placement, corner_weight=1.0, robust_scale_px=None)
        p1 = estimate_pose(found[0], k_mat, None, SIZE, rec.placement)
        for p in (p0, p1):
            assert p.reprojection_error_px < 1.0 and len(p.solutions) == 2
            assert np.allclose(cv2.Rodrigues(p.rvec)[0], p.R)
        # the plain least-squares fit has the smallest unweighted error by construction
        assert p0.reprojection_error_px <= p1.reprojection_error_px + 1e-9
        plain.append(_rot_err_deg(p0.R, r_mat))
        weighted.append(_rot_err_deg(p1.R, r_mat))
    assert np.mean(weighted) <= np.mean(plain) * 1.1


def test_placement_estimate_matches_renderer(setup):
    lookup, good = setup
    rng = np.random.default_rng(3)
    k_mat = sc.camera_matrix()
    rec = good[0]
    r_mat, t = sc.random_pose(rng, k_mat, SIZE, 200, 20, (320, 240))
    spec = sc.TagSpec(rec.points, rec.triangles, sc.pose_homography(k_mat, r_mat, t, SIZE), placement=rec.placement)
    scene = sc.render_scene((480, 640), [spec], rng, blur=0.5)
    d = Detector(lookup).detect(scene.image)[0]
    aff = placement_from_detection(d)
    assert np.allclose(aff, rec.placement, atol=0.01)


def test_pose_bad_arguments(setup):
    lookup, good = setup
    rng = np.random.default_rng(4)
    k_mat = sc.camera_matrix()
    rec = good[1]
    r_mat, t = sc.random_pose(rng, k_mat, SIZE, 180, 10, (320, 240))
    spec = sc.TagSpec(rec.points, rec.triangles, sc.pose_homography(k_mat, r_mat, t, SIZE), placement=rec.placement)
    d = Detector(lookup).detect(sc.render_scene((480, 640), [spec], rng).image)[0]
    with pytest.raises(UsageError):
        estimate_pose(d, np.eye(2), None, SIZE)
    with pytest.raises(UsageError):
        estimate_pose(d, k_mat, None, -1.0)
    with pytest.raises(UsageError):
        estimate_pose(d, k_mat, None, SIZE, np.eye(3))
    with pytest.raises(UsageError):
        estimate_pose(d, k_mat, None, SIZE, corner_weight=0.0)
    with pytest.raises(UsageError):
        estimate_pose(d, k_mat, None, SIZE, robust_scale_px=-1.0)
