"""Files: the point-set format, the bundled data and package resources (imports ``core`` only).

- :mod:`~ottag_db.files.pointfile`: ``.b08`` / ``.b16`` point-set files, streamed;
- :mod:`~ottag_db.files.bundled`: the bundled ``ottag-kNN.b08`` files and their manifest;
- :mod:`~ottag_db.files.resources`: where migrations and data live (wheel or checkout).
"""
