"""Type stubs of the compiled :mod:`ottag_native.refine`."""

from typing import Any

def sample_grid(
    a: Any,
    sd: Any,
    normal: Any,
    st: int,
    fractions: Any,
    offsets: Any,
    base_x: Any,
    base_y: Any,
    width: Any,
    wide: Any,
    grid: Any,
) -> None: ...
def level_crossings(
    values: Any,
    level: float,
    st: int,
    inward: Any,
    offsets: Any,
    middles: Any,
    base_x: Any,
    base_y: Any,
    normal: Any,
    wide: Any,
    px: Any,
    py: Any,
    valid: Any,
) -> None: ...
def inward_sides(normal: Any, offset: Any, quad: Any, out: Any) -> None: ...
def crossing_moments(
    px: Any, py: Any, valid: Any, mx: Any, my: Any, sxx: Any, sxy: Any, syy: Any, count: Any
) -> None: ...
def chain_moments(chains: list[Any], mx: Any, my: Any, sxx: Any, sxy: Any, syy: Any) -> None: ...
