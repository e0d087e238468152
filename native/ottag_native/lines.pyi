"""Type stubs of the compiled :mod:`ottag_native.lines`."""

from typing import Any

def lines_quad(
    poly: Any,
    tol: float,
    cos_tol: float,
    width: int,
    height: int,
    least_area: float,
    most_area: float,
    considered: int,
    min_support: float,
    out: Any,
) -> bool: ...
