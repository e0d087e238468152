"""Type stubs of the compiled :mod:`ottag_native.cluster`."""

from typing import Any

def vertex_groupings(
    vertices: Any, normal: Any, offset: Any, cap: float, sure: float, tol: float, max_doubtful: int
) -> list[tuple[list[tuple[float, float]], list[list[int]]]]: ...
