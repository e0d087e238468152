"""Type stubs of the compiled :mod:`ottag_native.blur`."""

from typing import Any

def side_blurs(
    profile: Any,
    smooth: Any,
    across: Any,
    lengths: Any,
    out: Any,
    across_step: float,
    smoothing_px: float,
    step_min_share: float,
    noise_height: float,
    min_height: float,
) -> None: ...
def side_samples(
    corners: Any,
    across: Any,
    along: Any,
    spread: Any,
    xs: Any,
    ys: Any,
    normals: Any,
    lengths: Any,
) -> None: ...
