"""The database (SQLAlchemy 2, Alembic): imports ``core`` and ``files``.

- :mod:`~ottag_db.store.db`: the one way in, :func:`~ottag_db.store.db.open_database`
  (backs up an older file, migrates to head);
- :mod:`~ottag_db.store.models`: the ORM schema;
- :mod:`~ottag_db.store.importer`: point files → order types, realizations and layouts;
- :mod:`~ottag_db.store.layouts`: layout and placement writes (import and migration 0004);
- :mod:`~ottag_db.store.numbering`: universal numbers;
- :mod:`~ottag_db.store.queries`: statistics, listings, details, ad-hoc IDs;
- :mod:`~ottag_db.store.tags`: printable tags (reads only);
- :mod:`~ottag_db.store.sources`: imported point files, listed and removed;
- :mod:`~ottag_db.store.flipgraph`: the stored flip graph;
- :mod:`~ottag_db.store.dictionaries` and :mod:`~ottag_db.store.dictionary_files`: named
  dictionaries and their JSON/CSV form;
- :mod:`~ottag_db.store.lookups`: decoder lookups (all order types or one dictionary).
"""
