"""Compiled kernels of ``ottag_db``'s decoder (Cython, built by ``pip install .``).

A separate top-level package, not a module of ``ottag_db``: the README's test command runs
``python -m pytest`` in the checkout, where the ``ottag_db`` found first is the source tree,
which holds no compiled files; this package is found where ``pip install .`` put it.
Each kernel computes exactly what the numpy or plain-Python code it replaced did (the same
operations in the same order and precision), so the decoder's readings do not depend on it.
"""
