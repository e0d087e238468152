"""The benchmarks' peers — ArUco 6×6 and AprilTag 3 (36h11), drawn at the same size and read with
their defaults — and the one way the benchmarks draw their ``--plot`` figures (matplotlib).

Both markers are drawn by ``cv2.aruco.generateImageMarker`` (AprilTag 36h11 through
``cv2.aruco.DICT_APRILTAG_36h11``, the same codes as the AprilTag library's family), their black
square the size of our data area, with a white border of a quarter side (our quiet zone). ArUco
is read by ``cv2.aruco.ArucoDetector`` with default parameters (``detectInvertedMarker`` for an
inverted marker), AprilTag 3 by ``pupil_apriltags.Detector()`` with its defaults (family
tag36h11, one thread, ``quad_decimate`` 2). AprilTag 3 has no inverted mode: an inverted marker
is given to it as it is, and it does not read it. ``pupil_apriltags`` and ``matplotlib`` come with
``pip install '.[bench]'``; they are imported inside the functions that use them.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

#: The id drawn for both peers in one-marker scenes.
MARKER_ID = 5
#: Peers of the benchmarks, in the order they are printed and plotted.
PEERS = ("ArUco 6x6", "AprilTag 36h11")
#: Marker patch (black square plus a white border of 1/4 side, unit square) → data-area unit square.
PATCH_TO_DATA_AREA = np.array([[1.5, 0, -0.25], [0, 1.5, -0.25], [0, 0, 1.0]])
#: ArUco corner order (top-left, top-right, bottom-right, bottom-left) from pupil_apriltags' order.
APRILTAG_TO_ARUCO_CORNERS = [1, 0, 3, 2]


def aruco_dictionary(peer: str) -> Any:
    """The ``cv2.aruco`` dictionary that draws ``peer`` (one of :data:`PEERS`)."""
    code = cv2.aruco.DICT_6X6_250 if peer == PEERS[0] else cv2.aruco.DICT_APRILTAG_36h11
    return cv2.aruco.getPredefinedDictionary(code)


def marker_patch(peer: str, marker_id: int = MARKER_ID, side_px: int = 400) -> NDArray[np.uint8]:
    """Marker ``marker_id`` of ``peer``, black square ``side_px`` wide, white border of a quarter side."""
    marker = cv2.aruco.generateImageMarker(aruco_dictionary(peer), marker_id, side_px)
    q = side_px // 4
    return np.asarray(cv2.copyMakeBorder(marker, q, q, q, q, cv2.BORDER_CONSTANT, value=255), np.uint8)


def _release_apriltag(detector: Any) -> None:
    """Free a ``pupil_apriltags.Detector``: the detector, then its tag families.

    pupil-apriltags 1.0.4 frees the families first, and then the detector, which still refers to
    them (a use-after-free in ``quick_decode_uninit``; pupil-labs/apriltags pull request 65). A
    benchmark that had built frames of 1280 × 960 px aborted at exit with
    "malloc(): mismatching next->prev_size" after printing its figures. Its own ``__del__`` then
    finds nothing left to free.
    """
    if detector.tag_detector_ptr is None:
        return
    lib = detector.libc
    lib.apriltag_detector_destroy.restype = None
    lib.apriltag_detector_destroy(detector.tag_detector_ptr)
    for family, pointer in detector.tag_families.items():
        destroy = getattr(lib, f"{family}_destroy")
        destroy.restype = None
        destroy(pointer)
    detector.tag_detector_ptr = None


class PeerReader:
    """Both peers' detectors with default parameters: ids read, and corners in ArUco's order."""

    def __init__(self) -> None:
        from pupil_apriltags import Detector as AprilTagDetector

        self.aruco = cv2.aruco.ArucoDetector(aruco_dictionary(PEERS[0]), cv2.aruco.DetectorParameters())
        inverted = cv2.aruco.DetectorParameters()
        inverted.detectInvertedMarker = True
        self.aruco_inverted = cv2.aruco.ArucoDetector(aruco_dictionary(PEERS[0]), inverted)
        self.apriltag = AprilTagDetector()
        # (freed in the right order when the reader goes or the interpreter exits)
        weakref.finalize(self, _release_apriltag, self.apriltag)

    def corners(self, peer: str, image: NDArray[np.uint8], inverted: bool = False) -> dict[int, NDArray[np.float64]]:
        """Marker id → its 4 corners (top-left, top-right, bottom-right, bottom-left; pixels)."""
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if peer == PEERS[0]:
            found, ids, _ = (self.aruco_inverted if inverted else self.aruco).detectMarkers(grey)
            if ids is None:
                return {}
            return {int(i): np.asarray(c, np.float64).reshape(4, 2) for i, c in zip(ids.ravel(), found, strict=True)}
        return {
            int(d.tag_id): np.asarray(d.corners, np.float64)[APRILTAG_TO_ARUCO_CORNERS]
            for d in self.apriltag.detect(np.ascontiguousarray(grey))
        }

    def ids(self, peer: str, image: NDArray[np.uint8], inverted: bool = False) -> set[int]:
        """The marker ids ``peer`` reads in ``image``."""
        return set(self.corners(peer, image, inverted))


def plot_lines(
    path: str | Path,
    panels: Sequence[tuple[str, str, str, Sequence[float], Mapping[str, Sequence[float]]]],
    *,
    width: float = 5.0,
) -> None:
    """Write line plots side by side as a small PNG.

    Parameters
    ----------
    path : str or Path
        The PNG to write.
    panels : sequence of (title, x label, y label, xs, {series name: ys})
        One panel each; a series whose name ends in ", inverted" is drawn dashed with open markers.
    width : float
        Inches per panel.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(width * len(panels), 3.4), squeeze=False)
    colours: dict[str, str] = {}
    for ax, (title, xlabel, ylabel, xs, series) in zip(axes[0], panels, strict=True):
        for name, ys in series.items():
            base = name.removesuffix(", inverted").removesuffix(", normal")
            colour = colours.setdefault(base, f"C{len(colours)}")
            dashed = name.endswith(", inverted")
            ax.plot(
                xs, ys, "--" if dashed else "-", marker="o", color=colour, label=name, markersize=3.5,
                markerfacecolor="white" if dashed else colour, linewidth=1.2,
            )  # fmt: skip
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    print(f"plot: {path}")


def plot_bars(path: str | Path, title: str, ylabel: str, groups: dict[str, dict[str, float]]) -> None:
    """Write grouped bars as a small PNG.

    Parameters
    ----------
    path : str or Path
        The PNG to write.
    title, ylabel : str
        Figure title and y-axis label.
    groups : dict
        Group label (x axis) → {detector: value}; every group names the same detectors.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(groups)
    names = list(next(iter(groups.values())))
    fig, ax = plt.subplots(figsize=(max(5.5, 1.6 + 1.6 * len(labels)), 3.2))
    step = 0.8 / len(names)
    for j, name in enumerate(names):
        xs = np.arange(len(labels)) + (j - (len(names) - 1) / 2) * step
        values = [groups[g][name] for g in labels]
        bars = ax.bar(xs, values, step * 0.9, label=name, color=f"C{j}")
        ax.bar_label(bars, fmt="%.2f", fontsize=7)
    ax.set_xticks(np.arange(len(labels)), labels)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    print(f"plot: {path}")
