"""Use cases: what a command does, combining the sub-packages below (imports any of them).

- :mod:`~ottag_db.app.importing`: which point files an import takes and its totals;
- :mod:`~ottag_db.app.reports`: the JSON of ``stats``/``show`` and the CSV of ``list``;
- :mod:`~ottag_db.app.export`: tag sheets and single-tag renders from the database;
- :mod:`~ottag_db.app.options`: sheet settings from option texts;
- :mod:`~ottag_db.app.detector`: :func:`~ottag_db.app.detector.open_detector`, a detector from a
  database, one of its dictionaries or a dictionary file;
- :mod:`~ottag_db.app.decode_batch`, :mod:`~ottag_db.app.decoding` and
  :mod:`~ottag_db.app.video`: decoding image and video files (options, JSON records, pose,
  drawings);
- :mod:`~ottag_db.app.boards` and :mod:`~ottag_db.app.calibration`: calibration boards and
  camera calibration from their images;
- :mod:`~ottag_db.app.dictionary_io`: dictionary exports as files;
- :mod:`~ottag_db.app.generating`: re-creating the bundled data.
"""
