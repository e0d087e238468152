"""Type stubs of the compiled :mod:`ottag_native.triangles`."""

from typing import Any

def fit_triangle(
    flat: Any, hull: Any, contour_area: float, perimeter: float
) -> tuple[int, int, int, int, int, int] | None: ...
def triangle_faults(verts: Any, quad: Any, side: float) -> int: ...
