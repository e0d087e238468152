"""Synthetic camera scenes: camera model, poses, rendering with ground truth, random scenes."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ottag_db.core.geometry import maximal_perturbation
from ottag_db.errors import UsageError
from ottag_db.printing import scenes as sc

SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])


def _at(image: np.ndarray, xy: np.ndarray) -> int:
    """Grey level of the pixel nearest to an (x, y) image point."""
    col, row = np.round(xy).astype(int)
    return int(image[row, col])


def _tag(points: list[list[int]], triangles: tuple[tuple[int, int, int], ...], text: str = "t") -> sc.DrawableTag:
    pts = np.asarray(points, dtype=np.float64)
    placed = np.c_[pts, np.ones(len(pts))] @ sc.PLACEMENT.T
    return sc.DrawableTag(text, pts, triangles, sc.PLACEMENT.copy(), maximal_perturbation(placed))


TRIANGLE = _tag([[20, 30], [230, 60], [110, 225]], ((0, 1, 2),), "3:011001100")
#: Five points, two triangles sharing no vertex plus a lone point (enough for random scenes).
FIVE = _tag([[20, 20], [120, 40], [40, 120], [230, 150], [150, 235]], ((0, 1, 2), (2, 3, 4)), "five")


def test_camera_matrix_centres_the_principal_point() -> None:
    k = sc.camera_matrix(500.0, 640, 480)
    assert k.tolist() == [[500, 0, 319.5], [0, 500, 239.5], [0, 0, 1]]


def test_frontal_pose_maps_the_data_area_to_a_square_of_the_asked_width() -> None:
    rng = np.random.default_rng(0)
    k_mat = sc.camera_matrix()
    r_mat, t = sc.random_pose(rng, k_mat, 0.1, 120.0, 0.0, (300.0, 200.0))
    assert np.allclose(r_mat @ r_mat.T, np.eye(3)) and np.linalg.det(r_mat) == pytest.approx(1.0)
    assert np.allclose(r_mat[:, 2], [0, 0, 1])  # no tilt: the tag faces the camera (z into it)
    corners = sc.project(sc.pose_homography(k_mat, r_mat, t, 0.1), SQUARE)
    sides = np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1)
    assert np.allclose(sides, 120.0)
    assert np.allclose(corners.mean(axis=0), [300.0, 200.0])


def test_a_pose_near_edge_on_off_the_optical_axis_shows_the_printed_face_not_its_mirror() -> None:
    # At 89° with the centre 40 px off the principal point the ray to the tag is 3° off the
    # axis: about half the tilt axes would put the camera behind the tag's plane, and the
    # frame would show the back of the paper, the tag mirrored (the data area's corners in
    # the other turning sense, so a decoder reads the mirror image's order type).
    k_mat = sc.camera_matrix()
    rng = np.random.default_rng(7)
    for _ in range(60):
        r_mat, t = sc.random_pose(rng, k_mat, 0.21, 98.0, 89.0, (360.0, 270.0))
        assert math.degrees(math.acos(r_mat[2, 2])) == pytest.approx(89.0)
        centre = t + r_mat @ np.array([0.105, 0.105, 0.0])
        assert r_mat[:, 2] @ centre > 0  # the camera is on the printed side of the plane
        x, y = sc.project(sc.pose_homography(k_mat, r_mat, t, 0.21), SQUARE).T
        # twice the signed area (x right, y down): positive for the unit square itself
        assert float(x @ np.roll(y, -1) - np.roll(x, -1) @ y) > 0


def test_tilt_foreshortens_and_the_tag_stays_in_front_of_the_camera() -> None:
    rng = np.random.default_rng(1)
    k_mat = sc.camera_matrix()
    r_mat, t = sc.random_pose(rng, k_mat, 0.1, 150.0, 60.0, (320.0, 240.0))
    assert math.degrees(math.acos(r_mat[2, 2])) == pytest.approx(60.0)
    corners = sc.project(sc.pose_homography(k_mat, r_mat, t, 0.1), SQUARE)
    d1, d2 = corners[2] - corners[0], corners[3] - corners[1]
    area = 0.5 * abs(d1[0] * d2[1] - d1[1] * d2[0])  # half the cross product of the diagonals
    assert area < 0.75 * 150.0**2  # about cos(60°) of the frontal area
    assert (r_mat @ np.c_[SQUARE * 0.1, np.zeros(4)].T + t[:, None])[2].min() > 0


def test_project_is_a_homography() -> None:
    h = np.array([[2.0, 0, 1], [0, 3, -1], [0, 0, 1]])
    assert sc.project(h, [[1, 1], [0, 2]]).tolist() == [[3, 2], [1, 5]]
    persp = np.array([[1.0, 0, 0], [0, 1, 0], [1, 0, 1]])
    assert sc.project(persp, [[1, 4]]).tolist() == [[0.5, 2.0]]


def test_drawable_from_file_order_relabels_points_and_triangles() -> None:
    points = [[10, 10], [200, 20], [100, 200], [60, 90]]
    tag = sc.drawable_from_file_order("x", points, [2, 0, 3, 1], [(0, 1, 2)], sc.PLACEMENT, 0.1)
    assert tag.points.tolist() == [[100, 200], [10, 10], [60, 90], [200, 20]]
    assert tag.triangles == ((1, 3, 0),)  # the same points, by label
    assert tag.k == 4 and tag.printed_mp_unit == 0.1
    with pytest.raises(UsageError):
        sc.drawable_from_file_order("x", points, [0, 0, 1, 2], [], sc.PLACEMENT, 0.1)


def test_render_scene_draws_tones_and_reports_the_points() -> None:
    rng = np.random.default_rng(2)
    k_mat = sc.camera_matrix()
    r_mat, t = sc.random_pose(rng, k_mat, 0.1, 200.0, 0.0, (320.0, 240.0))
    hom = sc.pose_homography(k_mat, r_mat, t, 0.1)
    spec = sc.TagSpec(TRIANGLE.points, TRIANGLE.triangles, hom, lambda_text=TRIANGLE.lambda_text)
    scene = sc.render_scene((480, 640), [spec], rng)
    img = scene.image
    assert img.shape == (480, 640) and img.dtype == np.uint8
    assert scene.tags == (spec,)
    expected = sc.project(hom, np.c_[TRIANGLE.points, np.ones(3)] @ sc.PLACEMENT.T)
    assert np.allclose(scene.truth_points[0], expected)
    corners = sc.project(hom, SQUARE)
    inside = corners[0] + 0.02 * (corners[2] - corners[0])  # data area, away from the triangle
    quiet = corners[0] - 0.1 * (corners[2] - corners[0])
    centroid = expected.mean(axis=0)
    assert img[5, 5] == 200  # background
    assert _at(img, quiet) == 235  # white quiet zone
    assert _at(img, inside) == 30  # black data area
    assert _at(img, centroid) == 235  # white triangle
    inverted = sc.render_scene((480, 640), [replace(spec, polarity="inverted")], rng).image
    assert _at(inverted, inside) == 235
    assert _at(inverted, centroid) == 30


def test_render_scene_degradations_follow_the_seed() -> None:
    spec = sc.posed_spec(TRIANGLE, np.random.default_rng(3), 150.0, 30.0)
    kwargs = {"gradient": 0.4, "blur": 0.8, "noise": 3.0, "jpeg": 80}
    a = sc.render_scene((240, 320), [spec], np.random.default_rng(4), **kwargs).image
    b = sc.render_scene((240, 320), [spec], np.random.default_rng(4), **kwargs).image
    c = sc.render_scene((240, 320), [spec], np.random.default_rng(5), **kwargs).image
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    with pytest.raises(UsageError):
        sc.render_scene((240, 320), [spec], np.random.default_rng(4), jpeg=101)


def test_extra_patches_are_drawn_under_the_tags() -> None:
    patch = np.zeros((10, 10), np.uint8)
    hom = np.array([[100.0, 0, 50], [0, 100, 50], [0, 0, 1]])  # unit square → (50 … 150) px
    img = sc.render_scene((200, 200), [], np.random.default_rng(0), extra=[(patch, hom)]).image
    assert img[100, 100] == 0 and img[10, 10] == 200


def test_posed_spec_keeps_the_tag_and_checks_the_polarity() -> None:
    spec = sc.posed_spec(FIVE, np.random.default_rng(6), 180.0, 20.0, "inverted")
    assert spec.polarity == "inverted" and spec.lambda_text == "five"
    assert spec.points is FIVE.points and spec.triangles == FIVE.triangles
    with pytest.raises(UsageError):
        sc.posed_spec(FIVE, np.random.default_rng(6), 180.0, 20.0, "sideways")  # type: ignore[arg-type]


def test_min_width_px() -> None:
    assert sc.min_width_px(0.5) == 50.0
    assert sc.min_width_px(0.01) == pytest.approx(sc.MARGIN_PX / 0.02)


def test_random_scene_keeps_every_tag_readable_and_apart() -> None:
    tags = [TRIANGLE, FIVE]
    first = sc.random_scene(np.random.default_rng(7), tags, n_tags=3)
    again = sc.random_scene(np.random.default_rng(7), tags, n_tags=3)
    assert np.array_equal(first.image, again.image)
    assert 1 <= len(first.tags) <= 3
    boxes = []
    for spec, truth in zip(first.tags, first.truth_points, strict=True):
        assert spec.lambda_text in {"3:011001100", "five"}
        corners = sc.project(spec.homography, SQUARE)
        assert np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1).min() >= sc.MIN_SIDE_PX
        assert 2 * maximal_perturbation(truth) >= sc.MIN_IMAGE_MARGIN_PX
        q = spec.quiet
        quiet = sc.project(spec.homography, [[-q, -q], [1 + q, -q], [1 + q, 1 + q], [-q, 1 + q]])
        assert quiet.min() >= 0 and quiet[:, 0].max() < 640 and quiet[:, 1].max() < 480
        boxes.append((*quiet.min(axis=0), *quiet.max(axis=0)))
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert a[2] < b[0] or b[2] < a[0] or a[3] < b[1] or b[3] < a[1]
    with pytest.raises(UsageError):
        sc.random_scene(np.random.default_rng(7), [])
