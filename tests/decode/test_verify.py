"""Verification stage: homographies from point–line incidences, corner order, the decision."""

from __future__ import annotations

import numpy as np

from ottag_db.core.lookup import LookupEntry
from ottag_db.decode import DetectorParams
from ottag_db.decode.types import Detection, Quad, Rejection
from ottag_db.decode.verify import (
    apply_homography,
    homography_from_lines,
    line_system,
    map_corners_back,
    model,
    tag_plane_corner_order,
    verify,
)

H = np.array([[1.2, 0.1, 30.0], [-0.05, 0.9, 40.0], [2e-4, -1e-4, 1.0]])
SRC = np.array([[0, 0], [100, 10], [40, 90], [120, 120], [200, 60], [160, 200.0]])


def _lines_through(pts: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Two lines through every point (towards its two neighbours in the list)."""
    out = []
    for i in range(len(pts)):
        normals, offsets = [], []
        for j in ((i + 1) % len(pts), (i + 2) % len(pts)):
            d = pts[j] - pts[i]
            n = np.array([-d[1], d[0]]) / np.hypot(d[0], d[1])
            normals.append(n)
            offsets.append(float(n @ pts[i]))
        out.append((np.array(normals), np.array(offsets)))
    return out


def test_homography_from_lines_recovers_the_map() -> None:
    dst = apply_homography(H, SRC)
    system = line_system(_lines_through(dst))
    assert system is not None
    hmat = homography_from_lines(model(SRC), system, system.owner)
    assert hmat is not None and np.allclose(hmat, H, rtol=1e-6, atol=1e-6)
    assert line_system(_lines_through(dst)[:3]) is None  # 6 lines: too few


def test_corners_back_and_their_order() -> None:
    plane = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]) * 255
    img = apply_homography(H, plane)
    back = map_corners_back(H, img)
    assert back is not None and np.allclose(back, plane)
    assert map_corners_back(np.zeros((3, 3)), img) is None
    rotated = img[[2, 3, 0, 1]]
    assert np.allclose(tag_plane_corner_order(rotated, plane[[2, 3, 0, 1]].tolist()), img)
    assert np.array_equal(tag_plane_corner_order(img, [[np.inf, 0]] * 4), img)


def _entry(real: np.ndarray) -> LookupEntry:
    return LookupEntry("6:x", 6, 1, True, (real,), 5)


def test_verify_accepts_the_realization_and_rejects_another() -> None:
    dst = apply_homography(H, SRC)
    lines = _lines_through(dst)
    corners = apply_homography(H, np.array([[0, 0], [255, 0], [255, 255], [0, 255.0]]))
    quad = Quad("normal", corners, 200.0**2)
    ident = [tuple(range(6))]
    res = verify(_entry(SRC), dst, lines, ident, corners, quad, 5.0, "6:x", DetectorParams())
    assert isinstance(res, Detection) and res.homography is not None
    assert res.reprojection_error_px is not None and res.reprojection_error_px < 1e-6
    other = SRC.copy()
    other[3] = [20, 180]
    rej = verify(_entry(other), dst, lines, ident, corners, quad, 5.0, "6:x", DetectorParams())
    assert isinstance(rej, Rejection) and rej.reason == "verification" and rej.lambda_text == "6:x"
    loose = verify(_entry(other), dst, lines, ident, corners, quad, 5.0, "6:x", DetectorParams(verify=False))
    assert isinstance(loose, Detection)
    none = verify(_entry(SRC[:5]), dst, lines, ident, corners, quad, 5.0, "6:x", DetectorParams())
    assert isinstance(none, Rejection) and none.detail == "no realization"
