"""A hidden corner takes its printed position from the points and the seen corners together."""

from __future__ import annotations

import cv2
import numpy as np

from ottag_db.decode.placement_check import printed_corners

_UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def test_the_seen_corners_hold_the_perspective_of_a_hidden_one() -> None:
    """Points measured to 0.15 px inside the middle of a strongly foreshortened data area fit a
    homography whose perspective is loose at the corners: by itself it can take a corner
    measured where it is for a hidden one, and it places a hidden corner loosely. Fitted with
    the corners, every corner measured where it is counts as seen, the covered one does not,
    and it lands closer to the truth, over many draws of the points' errors."""
    placement = np.array([[0.01, 0.0, 0.2], [0.0, 0.01, 0.2]])  # plane → data area: points in [0.2, 0.8]
    to_image = cv2.getPerspectiveTransform(
        _UNIT.astype(np.float32), np.float32([[100, 100], [260, 130], [250, 230], [110, 250]])
    ).astype(np.float64)  # data area → image, foreshortened
    affine = np.vstack([placement, [0.0, 0.0, 1.0]])
    truth = cv2.perspectiveTransform(_UNIT.reshape(1, 4, 2), to_image)[0]
    rng = np.random.default_rng(3)
    plane = rng.uniform(0, 60, (8, 2))  # the realization's points
    image = cv2.perspectiveTransform(plane.reshape(1, 8, 2), to_image @ affine)[0]
    errors: dict[bool, list[float]] = {False: [], True: []}
    for _ in range(30):
        seen_at = image + rng.normal(0, 0.15, image.shape)
        hmat, _ = cv2.findHomography(plane.astype(np.float32), seen_at.astype(np.float32), 0)
        measured = truth.copy()
        measured[2] += [8.0, 6.0]  # covered: measured where the cover's edge is
        for with_points in (False, True):
            points = (plane, seen_at) if with_points else None
            corners, seen = printed_corners(placement, hmat, measured, 2.5, True, points)
            assert not seen[2]
            np.testing.assert_array_equal(corners[seen], measured[seen])  # the seen ones as measured
            if with_points:  # every corner measured where it is counts as seen
                assert seen.tolist() == [True, True, False, True]
            errors[with_points].append(float(np.linalg.norm(corners[~seen] - truth[~seen], axis=1).max()))
    assert np.mean(errors[True]) < 0.7 * np.mean(errors[False])
