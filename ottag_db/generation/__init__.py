"""Generation of the bundled data (imports ``core`` and ``files`` only).

- :mod:`~ottag_db.generation.enumeration`: all order types of 3 … 8 points from scratch,
  by inserting a point into every cell of a line arrangement
  (:mod:`~ottag_db.generation.arrangement`);
- :mod:`~ottag_db.generation.realize`: each order type on the 256 × 256 grid with a large MP,
  in two stages: :mod:`~ottag_db.generation.continuous` (SLSQP) and
  :mod:`~ottag_db.generation.rounding` (rounding, integer search, tilt-robust choice), with
  the figures of merit in :mod:`~ottag_db.generation.objective` and the search effort in
  :mod:`~ottag_db.generation.effort`;
- :mod:`~ottag_db.generation.parallel` runs the realization's batches in process or on Dask,
  :mod:`~ottag_db.generation.checkpoint` keeps finished batches for a resumed run;
- writing the files ``ottag-kNN.b08`` and ``manifest.json`` from both is the use case
  :mod:`ottag_db.app.generating`.
"""
