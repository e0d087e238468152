"""ottag-db: Order Type Tags — order-type database, tag sheets and a perspective-invariant decoder.

The public names below are resolved lazily (PEP 562): ``import ottag_db`` costs almost nothing,
and ``ottag_db.Detector`` imports OpenCV only when it is first asked for. This keeps
``ottag-db --version`` fast, whose CLI package sits inside this one. ``_EXPORTS`` is the one map
from a public name to the module that defines it; the ``TYPE_CHECKING`` block repeats it for
type checkers and must stay in step with it (``tests/cli/test_lazy_exports.py`` checks both).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: Public name → module that defines it. Resolved on first attribute access.
_EXPORTS: dict[str, str] = {
    # app
    "open_detector": "ottag_db.app.detector",
    "Camera": "ottag_db.app.decoding",
    "load_camera": "ottag_db.app.decoding",
    "TagFilter": "ottag_db.app.export",
    "export_sheet": "ottag_db.app.export",
    "render_tag": "ottag_db.app.export",
    # core
    "MP_THRESHOLDS": "ottag_db.core.types",
    "CanonicalBatch": "ottag_db.core.canonical",
    "CanonicalForm": "ottag_db.core.canonical",
    "canonical_batch": "ottag_db.core.canonical",
    "canonical_form": "ottag_db.core.canonical",
    "canonical_lambda": "ottag_db.core.canonical",
    "canonical_orderings": "ottag_db.core.canonical",
    "canonicalize_lambdas": "ottag_db.core.canonical",
    "lambda_orderings": "ottag_db.core.canonical",
    "lambda_text": "ottag_db.core.canonical",
    "lambda_texts": "ottag_db.core.canonical",
    "mirror_lambdas": "ottag_db.core.canonical",
    "parse_lambda_text": "ottag_db.core.canonical",
    "relabel_lambda": "ottag_db.core.canonical",
    "FlipEdge": "ottag_db.core.flips",
    "flip_neighbours": "ottag_db.core.flips",
    "check_general_position": "ottag_db.core.geometry",
    "general_position_mask": "ottag_db.core.geometry",
    "hull_size": "ottag_db.core.geometry",
    "hull_sizes": "ottag_db.core.geometry",
    "lambda_matrices": "ottag_db.core.geometry",
    "lambda_matrix": "ottag_db.core.geometry",
    "maximal_perturbation": "ottag_db.core.geometry",
    "maximal_perturbations": "ottag_db.core.geometry",
    "orientation_tensor": "ottag_db.core.geometry",
    "Layout": "ottag_db.core.layout",
    "compute_layout": "ottag_db.core.layout",
    "compute_layouts": "ottag_db.core.layout",
    "validate_layout": "ottag_db.core.layout_check",
    "LookupEntry": "ottag_db.core.lookup",
    "MemoryLookup": "ottag_db.core.lookup",
    "TagLookup": "ottag_db.core.lookup",
    "tag_placement": "ottag_db.core.placement",
    # decode
    "Detection": "ottag_db.decode.types",
    "Detector": "ottag_db.decode.detector",
    "DetectorParams": "ottag_db.decode.params",
    "Rejected": "ottag_db.decode.types",
    "Pose": "ottag_db.decode.pose",
    "estimate_pose": "ottag_db.decode.pose",
    # errors
    "DatabaseError": "ottag_db.errors",
    "DecodeError": "ottag_db.errors",
    "DictionaryError": "ottag_db.errors",
    "ExportError": "ottag_db.errors",
    "GeneralPositionError": "ottag_db.errors",
    "LambdaFormatError": "ottag_db.errors",
    "NotFoundError": "ottag_db.errors",
    "OttagError": "ottag_db.errors",
    "PointFileError": "ottag_db.errors",
    "UsageError": "ottag_db.errors",
    # files
    "OFFICIAL_RECORD_COUNTS": "ottag_db.files.pointfile",
    "PointFileInfo": "ottag_db.files.pointfile",
    "inspect_point_file": "ottag_db.files.pointfile",
    "iter_point_chunks": "ottag_db.files.pointfile",
    "read_point_file": "ottag_db.files.pointfile",
    "write_point_file": "ottag_db.files.pointfile",
    # generation
    "generate_database": "ottag_db.app.generating",
    "maximize_mp": "ottag_db.generation.realize",
    # printing
    "TagGeometry": "ottag_db.printing.geometry",
    "build_tag_geometry": "ottag_db.printing.geometry",
    "render_raster": "ottag_db.printing.raster",
    "render_svg": "ottag_db.printing.svg",
    "SheetOptions": "ottag_db.printing.sheet",
    "SheetTag": "ottag_db.printing.sheet",
    "write_tag_sheet": "ottag_db.printing.sheet",
    # store
    "Database": "ottag_db.store.db",
    "head_revision": "ottag_db.store.db",
    "open_database": "ottag_db.store.db",
    "DictionaryInfo": "ottag_db.store.dictionaries",
    "DictionaryOptions": "ottag_db.store.dictionaries",
    "create_dictionary": "ottag_db.store.dictionaries",
    "dictionary_lookup": "ottag_db.store.lookups",
    "export_dictionary": "ottag_db.store.dictionary_files",
    "get_dictionary": "ottag_db.store.dictionaries",
    "import_dictionary": "ottag_db.store.dictionary_files",
    "ImportReport": "ottag_db.store.importer",
    "import_point_file": "ottag_db.store.importer",
    "import_point_files": "ottag_db.store.importer",
    "IdResult": "ottag_db.store.queries",
    "KStats": "ottag_db.store.queries",
    "OrderTypeDetail": "ottag_db.store.queries",
    "OrderTypeSummary": "ottag_db.store.queries",
    "database_stats": "ottag_db.store.queries",
    "get_order_type": "ottag_db.store.queries",
    "identify_points": "ottag_db.store.queries",
    "list_order_types": "ottag_db.store.queries",
    "TagRecord": "ottag_db.store.tags",
    "ensure_layouts": "ottag_db.store.layouts",
    "load_lookup": "ottag_db.store.lookups",
    "select_tags": "ottag_db.store.tags",
}

__all__ = [
    "MP_THRESHOLDS",
    "OFFICIAL_RECORD_COUNTS",
    "Camera",
    "CanonicalBatch",
    "CanonicalForm",
    "Database",
    "DatabaseError",
    "DecodeError",
    "Detection",
    "Detector",
    "DetectorParams",
    "DictionaryError",
    "DictionaryInfo",
    "DictionaryOptions",
    "ExportError",
    "FlipEdge",
    "GeneralPositionError",
    "IdResult",
    "ImportReport",
    "KStats",
    "LambdaFormatError",
    "Layout",
    "LookupEntry",
    "MemoryLookup",
    "NotFoundError",
    "OrderTypeDetail",
    "OrderTypeSummary",
    "OttagError",
    "PointFileError",
    "PointFileInfo",
    "Pose",
    "Rejected",
    "SheetOptions",
    "SheetTag",
    "TagFilter",
    "TagGeometry",
    "TagLookup",
    "TagRecord",
    "UsageError",
    "__version__",
    "build_tag_geometry",
    "canonical_batch",
    "canonical_form",
    "canonical_lambda",
    "canonical_orderings",
    "canonicalize_lambdas",
    "check_general_position",
    "compute_layout",
    "compute_layouts",
    "create_dictionary",
    "database_stats",
    "dictionary_lookup",
    "ensure_layouts",
    "estimate_pose",
    "export_dictionary",
    "export_sheet",
    "flip_neighbours",
    "general_position_mask",
    "generate_database",
    "get_dictionary",
    "get_order_type",
    "head_revision",
    "hull_size",
    "hull_sizes",
    "identify_points",
    "import_dictionary",
    "import_point_file",
    "import_point_files",
    "inspect_point_file",
    "iter_point_chunks",
    "lambda_matrices",
    "lambda_matrix",
    "lambda_orderings",
    "lambda_text",
    "lambda_texts",
    "list_order_types",
    "load_camera",
    "load_lookup",
    "maximal_perturbation",
    "maximal_perturbations",
    "maximize_mp",
    "mirror_lambdas",
    "open_database",
    "open_detector",
    "orientation_tensor",
    "parse_lambda_text",
    "read_point_file",
    "relabel_lambda",
    "render_raster",
    "render_svg",
    "render_tag",
    "select_tags",
    "tag_placement",
    "validate_layout",
    "write_point_file",
    "write_tag_sheet",
]


def __getattr__(name: str) -> Any:
    """Import the module that defines public ``name`` and return the object (PEP 562).

    Parameters
    ----------
    name : str
        An attribute of the package that is not set on it yet.

    Returns
    -------
    Any
        The object ``name`` of its defining module (imported now if it was not yet).

    Raises
    ------
    AttributeError
        When ``name`` is not a public name of the package.
    """
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


def __dir__() -> list[str]:
    """The module's own attributes plus the lazily resolved public names."""
    return sorted({*globals(), *_EXPORTS})


if TYPE_CHECKING:
    from ottag_db.app.decoding import Camera, load_camera
    from ottag_db.app.detector import open_detector
    from ottag_db.app.export import TagFilter, export_sheet, render_tag
    from ottag_db.app.generating import generate_database
    from ottag_db.core.canonical import (
        CanonicalBatch,
        CanonicalForm,
        canonical_batch,
        canonical_form,
        canonical_lambda,
        canonical_orderings,
        canonicalize_lambdas,
        lambda_orderings,
        lambda_text,
        lambda_texts,
        mirror_lambdas,
        parse_lambda_text,
        relabel_lambda,
    )
    from ottag_db.core.flips import FlipEdge, flip_neighbours
    from ottag_db.core.geometry import (
        check_general_position,
        general_position_mask,
        hull_size,
        hull_sizes,
        lambda_matrices,
        lambda_matrix,
        maximal_perturbation,
        maximal_perturbations,
        orientation_tensor,
    )
    from ottag_db.core.layout import Layout, compute_layout, compute_layouts
    from ottag_db.core.layout_check import validate_layout
    from ottag_db.core.lookup import LookupEntry, MemoryLookup, TagLookup
    from ottag_db.core.placement import tag_placement
    from ottag_db.core.types import MP_THRESHOLDS
    from ottag_db.decode.detector import Detector
    from ottag_db.decode.params import DetectorParams
    from ottag_db.decode.pose import Pose, estimate_pose
    from ottag_db.decode.types import Detection, Rejected
    from ottag_db.errors import (
        DatabaseError,
        DecodeError,
        DictionaryError,
        ExportError,
        GeneralPositionError,
        LambdaFormatError,
        NotFoundError,
        OttagError,
        PointFileError,
        UsageError,
    )
    from ottag_db.files.pointfile import (
        OFFICIAL_RECORD_COUNTS,
        PointFileInfo,
        inspect_point_file,
        iter_point_chunks,
        read_point_file,
        write_point_file,
    )
    from ottag_db.generation.realize import maximize_mp
    from ottag_db.printing.geometry import TagGeometry, build_tag_geometry
    from ottag_db.printing.raster import render_raster
    from ottag_db.printing.sheet import SheetOptions, SheetTag, write_tag_sheet
    from ottag_db.printing.svg import render_svg
    from ottag_db.store.db import Database, head_revision, open_database
    from ottag_db.store.dictionaries import (
        DictionaryInfo,
        DictionaryOptions,
        create_dictionary,
        get_dictionary,
    )
    from ottag_db.store.dictionary_files import export_dictionary, import_dictionary
    from ottag_db.store.importer import ImportReport, import_point_file, import_point_files
    from ottag_db.store.layouts import ensure_layouts
    from ottag_db.store.lookups import dictionary_lookup, load_lookup
    from ottag_db.store.queries import (
        IdResult,
        KStats,
        OrderTypeDetail,
        OrderTypeSummary,
        database_stats,
        get_order_type,
        identify_points,
        list_order_types,
    )
    from ottag_db.store.tags import TagRecord, select_tags
