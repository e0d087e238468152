"""The decoder's compiled kernels (``native/ottag_native``, Cython); everything else about the
package is in ``pyproject.toml``. ``pip install .`` builds them (Cython is a build requirement).

Built without fused multiply-adds (``-ffp-contract=off``): each kernel computes exactly what its
numpy or plain-Python formulation does, operation for operation.
"""

from setuptools import Extension, setup

KERNELS = ("blur", "cluster", "histogram", "lines", "refine", "triangles")

setup(
    ext_modules=[
        Extension(
            f"ottag_native.{name}", [f"native/ottag_native/{name}.pyx"], extra_compile_args=["-O2", "-ffp-contract=off"]
        )
        for name in KERNELS
    ]
)
