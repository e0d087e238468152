"""Pure numpy building blocks shared by every other sub-package (no I/O; imports only ``errors``).

- :mod:`~ottag_db.core.geometry`: orientations, λ-matrices, hulls, MP, general position;
- :mod:`~ottag_db.core.canonical`: canonical orderings and IDs (paper Algorithms 1 and 2);
- :mod:`~ottag_db.core.single_set`: one measured set (the decoder's path): orientations,
  margin, λ and orderings from one table;
- :mod:`~ottag_db.core.flips`: the flip graph of the order types of one k;
- :mod:`~ottag_db.core.layout`: triangle layouts (the search), with
  :mod:`~ottag_db.core.layout_figures` (what it measures) and
  :mod:`~ottag_db.core.layout_check` (the independent checker);
- :mod:`~ottag_db.core.placement`: the affine map into a tag's data area;
- :mod:`~ottag_db.core.lookup`: the lookup protocol between the decoder and a store;
- :mod:`~ottag_db.core.types`: shared types and constants.
"""
