"""Drawing tags (imports ``core`` only): geometry, raster, SVG, PDF sheets, synthetic camera frames.

- :mod:`~ottag_db.printing.geometry`: a placed point set with its layout, tones and sizes;
- :mod:`~ottag_db.printing.raster`, :mod:`~ottag_db.printing.svg`, :mod:`~ottag_db.printing.pdf`:
  one tag as PNG pixels, an SVG document, or on a reportlab canvas;
- :mod:`~ottag_db.printing.sheet`: print-ready PDF sheets, with the page grid in
  :mod:`~ottag_db.printing.sheet_layout` (packing, shared quiet zones) and the page drawing
  (header, footer, ruler) in :mod:`~ottag_db.printing.sheet_draw`;
- :mod:`~ottag_db.printing.board`: a calibration-board page, and a distorting camera for
  synthetic views of it;
- :mod:`~ottag_db.printing.output`: output paths checked before drawing;
- :mod:`~ottag_db.printing.scenes` and :mod:`~ottag_db.printing.camera`: tags seen by a
  pinhole camera, with blur, noise, light and JPEG (decoder tests and benchmarks).
"""
