"""Type stubs of the compiled :mod:`ottag_native.histogram`."""

from typing import Any

def otsu_split(hist: Any, out: Any) -> bool: ...
