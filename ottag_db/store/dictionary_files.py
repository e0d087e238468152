"""Dictionary files: export a stored dictionary as JSON or CSV; read, validate and import one.

A JSON export (format ``ottag-dictionary/1``) is the complete definition of a dictionary:
every tag with its points, triangles, polarity, number and λ. :func:`parse_dictionary` is the
one validation of such a file, used by ``dictionary import`` and ``decode --dictionary-file``.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select

from ottag_db.core.canonical import canonical_form, canonicalize_lambdas, parse_lambda_text
from ottag_db.core.geometry import check_general_position, maximal_perturbation, maximal_perturbations
from ottag_db.core.layout import layout_quality, layout_supported
from ottag_db.core.layout_check import validate_layout
from ottag_db.core.lookup import MemoryLookup
from ottag_db.core.placement import apply_placements, tag_placements
from ottag_db.errors import DictionaryError, GeneralPositionError, LambdaFormatError, UsageError
from ottag_db.store.db import Database
from ottag_db.store.dictionaries import (
    DictionaryInfo,
    check_dictionary_name,
    dictionary_source_name,
    get_dictionary,
)
from ottag_db.store.lookups import MemberGeometry, member_lookup
from ottag_db.store.models import (
    Dictionary,
    DictionaryTag,
    LayoutRow,
    OrderType,
    Realization,
    Source,
    coordinates_to_blobs,
    labelings_to_texts,
    triangles_to_text,
)

#: The ``format`` of a JSON export.
FORMAT = "ottag-dictionary/1"

__all__ = [
    "FORMAT",
    "DictionaryDocument",
    "FileTag",
    "export_dictionary",
    "import_dictionary",
    "parse_dictionary",
]


def export_dictionary(db: Database, name: str, fmt: str = "json") -> str:
    """The dictionary as JSON (``name``, ``min_flip_distance``, ``parameters``, ``tags``) or CSV.

    Parameters
    ----------
    db : Database
        An open database (only read).
    name : str
        Dictionary name.
    fmt : str
        ``"json"`` (format ``ottag-dictionary/1``, see README) or ``"csv"`` (one row per tag).

    Returns
    -------
    str
        The file text.

    Raises
    ------
    NotFoundError
        No dictionary of that name.
    UsageError
        Another ``fmt``.
    """
    info = get_dictionary(db, name)
    if fmt == "json":
        return json.dumps(
            {
                "format": FORMAT,
                "name": info.name,
                "min_flip_distance": info.min_flip_distance,
                "parameters": info.parameters,
                "orientation": "screen coordinates (x right, y down); p left of pi->pj when "
                "(xj-xi)(yp-yi)-(yj-yi)(xp-xi) < 0",
                "tags": [m.as_json() for m in info.members],
            },
            indent=1,
        )
    if fmt == "csv":
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["number", "lambda", "k", "polarity", "universal_number", "points", "triangles", "mp", "unique_min"])
        for m in info.members:
            w.writerow(
                [
                    m.number,
                    m.lambda_text,
                    m.k,
                    m.polarity,
                    "" if m.universal_number is None else m.universal_number,
                    " ".join(f"{x},{y}" for x, y in m.points),
                    " ".join(",".join(str(i) for i in t) for t in m.triangles),
                    f"{m.mp:.6f}",
                    int(m.unique_min),
                ]
            )
        return buf.getvalue()
    raise UsageError(f"format must be json or csv, got {fmt!r}")


@dataclass(frozen=True)
class FileTag:
    """One validated tag of a dictionary file.

    ``points`` are the grid coordinates in file order (``(k, 2)`` int64, screen convention),
    ``triangles`` index triples into them, ``labeling[l]`` the file index of the point with
    canonical label ``l``; ``lambda_text`` is the canonical ID of the points (equal to the
    file's ``lambda``); ``mp`` in grid units.
    """

    number: int
    lambda_text: str
    polarity: str
    points: NDArray[np.int64]
    triangles: tuple[tuple[int, int, int], ...]
    labeling: tuple[int, ...]
    unique_min: bool
    universal_number: int | None
    mp: float

    @property
    def k(self) -> int:
        """Number of points."""
        return int(self.points.shape[0])

    def canonical_points(self) -> NDArray[np.float64]:
        """The points in canonical label order (row ``l`` = label ``l``), float64 grid units."""
        return self.points[list(self.labeling)].astype(np.float64)


@dataclass(frozen=True)
class DictionaryDocument:
    """A dictionary file (format ``ottag-dictionary/1``) whose every tag passed validation."""

    name: str
    min_flip_distance: int
    parameters: dict[str, Any]
    tags: tuple[FileTag, ...]

    def lookup(self) -> MemoryLookup:
        """The decoder's lookup of this dictionary alone, no database needed.

        Returns
        -------
        MemoryLookup
            As :func:`ottag_db.store.lookups.dictionary_lookup` gives for the imported
            dictionary: every member verified against exactly its points. ``order_type_id``
            is the position (from 1) of the order type among the file's distinct IDs (sorted).
        """
        ids = self.order_type_ids()
        return member_lookup(
            self.name,
            [
                MemberGeometry(
                    number=t.number,
                    polarity=t.polarity,
                    lambda_text=t.lambda_text,
                    k=t.k,
                    order_type_id=ids[t.lambda_text],
                    unique_min=t.unique_min,
                    realizations=(t.canonical_points(),),
                )
                for t in self.tags
            ],
        )

    def order_type_ids(self) -> dict[str, int]:
        """Canonical ID → its position (from 1) among the file's distinct IDs (sorted by k, then ID)."""
        texts = sorted({t.lambda_text for t in self.tags}, key=lambda x: (len(x), x))
        return {t: i for i, t in enumerate(texts, start=1)}

    def universal_numbers(self) -> dict[int, int | None]:
        """Order-type id of :meth:`lookup` → the universal number the file gives (or None)."""
        ids = self.order_type_ids()
        return {ids[t.lambda_text]: t.universal_number for t in self.tags}


def parse_dictionary(text: str, *, source: str = "<input>") -> DictionaryDocument:
    """Read and validate a dictionary file: the one check for ``dictionary import`` and
    ``decode --dictionary-file``.

    Every tag must have an integer ``number`` (unique), ``polarity`` ``normal`` or
    ``inverted``, ``points`` (k = 3, 5 … 8 integer grid points 0 … 65535, file order) in
    general position whose order type is ``lambda``, and ``triangles`` obeying the tag layout
    rules (:func:`ottag_db.core.layout_check.validate_layout`).

    Parameters
    ----------
    text : str
        The JSON text (as written by :func:`export_dictionary`).
    source : str
        Where the text came from, for messages.

    Returns
    -------
    DictionaryDocument
        The validated dictionary.

    Raises
    ------
    DictionaryError
        Not a dictionary export, or the first bad tag: ``SOURCE: tag N (λ ID): problem``.
    """
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DictionaryError(f"{source}: not JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})") from exc
    if not isinstance(data, dict) or "tags" not in data or "name" not in data:
        raise DictionaryError(f"{source}: not an ottag dictionary export (needs 'name' and 'tags')")
    fmt = data.get("format", FORMAT)
    if fmt != FORMAT:
        raise DictionaryError(f"{source}: format {fmt!r} is not {FORMAT!r}; export it again with this version")
    tags = data["tags"]
    if not isinstance(tags, list) or not tags:
        raise DictionaryError(f"{source}: 'tags' must be a non-empty list")
    distance = data.get("min_flip_distance", 1)
    if not isinstance(distance, int) or isinstance(distance, bool) or distance < 1:
        raise DictionaryError(f"{source}: 'min_flip_distance' must be an integer of at least 1")
    parameters = data.get("parameters", {})
    if not isinstance(parameters, dict):
        raise DictionaryError(f"{source}: 'parameters' must be an object")
    out: list[FileTag] = []
    seen: set[int] = set()
    for i, tag in enumerate(tags):
        t = _parse_tag(tag, i, source)
        if t.number in seen:
            raise DictionaryError(f"{source}: tag {t.number} (λ {t.lambda_text}): number {t.number} appears twice")
        seen.add(t.number)
        out.append(t)
    return DictionaryDocument(
        name=str(data["name"]), min_flip_distance=distance, parameters=parameters, tags=tuple(out)
    )


def _int(value: object) -> int | None:
    """``value`` when it is a JSON integer (not a bool), else None."""
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _parse_tag(tag: object, index: int, source: str) -> FileTag:
    """Validate entry ``index`` of ``tags`` (see :func:`parse_dictionary`)."""
    if not isinstance(tag, dict):
        raise DictionaryError(f"{source}: tag entry {index}: must be an object with number, lambda, points, triangles")
    number = _int(tag.get("number"))
    if number is None or number < 0:
        raise DictionaryError(f"{source}: tag entry {index}: 'number' must be a non-negative integer")
    given = tag.get("lambda")
    where = f"{source}: tag {number} (λ {given})"
    try:
        lam = parse_lambda_text(str(given))
    except (LambdaFormatError, ValueError) as exc:
        raise DictionaryError(f"{where}: 'lambda' is not an order-type ID k:digits ({exc})") from exc
    polarity = tag.get("polarity", "normal")
    if polarity not in ("normal", "inverted"):
        raise DictionaryError(f"{where}: polarity must be normal or inverted, got {polarity!r}")
    pts = _points(tag.get("points"), where)
    k = pts.shape[0]
    if k != lam.shape[0]:
        raise DictionaryError(f"{where}: {k} points but 'lambda' is a {lam.shape[0]}-point order type")
    if not layout_supported(k):
        raise DictionaryError(f"{where}: {k}-point tags cannot be drawn (k = 3, 5 … 9)")
    try:
        check_general_position(pts)
    except GeneralPositionError as exc:
        problem = str(exc).split(": ", 1)[-1]
        raise DictionaryError(f"{where}: {problem}; the points must be in general position") from exc
    form = canonical_form(pts)
    wanted = canonicalize_lambdas(lam[None]).texts()[0]
    if form.text != wanted:
        raise DictionaryError(
            f"{where}: the points are order type {form.text}, not 'lambda' — the file was edited or damaged"
        )
    triangles = _triangles(tag.get("triangles"), where)
    problems = validate_layout(pts, triangles)
    if problems:
        more = f" (and {len(problems) - 3} more)" if len(problems) > 3 else ""
        raise DictionaryError(f"{where}: triangles break the layout rules: {'; '.join(problems[:3])}{more}")
    universal = _int(tag.get("universal_number"))
    return FileTag(
        number=number,
        lambda_text=form.text,
        polarity=str(polarity),
        points=pts,
        triangles=tuple(sorted(tuple(sorted(t)) for t in triangles)),  # type: ignore[misc]
        labeling=form.labeling,
        unique_min=form.unique_min,
        universal_number=universal,
        mp=maximal_perturbation(pts),
    )


def _points(value: object, where: str) -> NDArray[np.int64]:
    """``points`` of a tag: a list of ``[x, y]`` integer grid coordinates 0 … 65535."""
    ok = isinstance(value, list) and all(
        isinstance(p, list) and len(p) == 2 and all(_int(c) is not None for c in p) for p in value
    )
    if not ok:
        raise DictionaryError(f"{where}: 'points' must be a list of [x, y] integer grid coordinates")
    pts = np.array(value, dtype=np.int64).reshape(-1, 2)
    if pts.size and (pts.min() < 0 or pts.max() > 65535):
        raise DictionaryError(f"{where}: point coordinates must be grid integers 0 … 65535")
    return pts


def _triangles(value: object, where: str) -> list[tuple[int, int, int]]:
    """``triangles`` of a tag: a non-empty list of ``[a, b, c]`` point indices."""
    out: list[tuple[int, int, int]] = []
    for t in value if isinstance(value, list) else []:
        idx = [_int(c) for c in t] if isinstance(t, list) and len(t) == 3 else []
        if len(idx) != 3 or any(i is None for i in idx):
            break
        out.append((int(t[0]), int(t[1]), int(t[2])))
    if not isinstance(value, list) or not value or len(out) != len(value):
        raise DictionaryError(f"{where}: 'triangles' must be a non-empty list of [a, b, c] point indices")
    return out


def import_dictionary(db: Database, text: str, *, source: str = "<input>", name: str | None = None) -> DictionaryInfo:
    """Store a dictionary from its JSON export, with the file's geometry, in one transaction.

    The file is validated by :func:`parse_dictionary` (nothing is written when a tag is
    bad). Each tag's points are stored as a realization of a source named
    :func:`~ottag_db.store.dictionaries.dictionary_source_name`, with the file's triangles as
    its layout and the placement ``import`` computes
    (:func:`ottag_db.core.placement.tag_placements`); the member is printed from and verified
    against exactly that geometry. Every member's order type must be in the database.

    Parameters
    ----------
    db : Database
        An open database.
    text : str
        The JSON text (as written by :func:`export_dictionary`).
    source : str
        Where the text came from, for messages.
    name : str, optional
        Store under this name instead of the file's.

    Returns
    -------
    DictionaryInfo
        The stored dictionary.

    Raises
    ------
    DictionaryError
        Not an export, a bad tag, an unknown order type or an existing name.
    UsageError
        A bad name.
    """
    doc = parse_dictionary(text, source=source)
    dict_name = name or doc.name
    check_dictionary_name(dict_name)
    with db.session() as s:
        if s.execute(select(Dictionary.id).where(Dictionary.name == dict_name)).first() is not None:
            raise DictionaryError(f"a dictionary named {dict_name!r} exists already; delete it or pass --name")
        texts = sorted({t.lambda_text for t in doc.tags})
        query = select(OrderType.lambda_text, OrderType.id).where(OrderType.lambda_text.in_(texts))
        ot_ids = {str(t): int(i) for t, i in s.execute(query).all()}
        for t in doc.tags:
            if t.lambda_text not in ot_ids:
                raise DictionaryError(
                    f"{source}: tag {t.number} (λ {t.lambda_text}): this order type is not in the database; "
                    "import the bundled data first (`ottag-db import`)"
                )
        d = Dictionary(
            name=dict_name,
            min_flip_distance=doc.min_flip_distance,
            parameters=json.dumps(doc.parameters, sort_keys=True),
            created_at=datetime.now(),
        )
        s.add(d)
        src = Source(
            file_name=dictionary_source_name(dict_name),
            sha256=hashlib.sha256(f"{dict_name}\n{text}".encode()).hexdigest(),
            n=max(t.k for t in doc.tags),
            coordinate_bits=8 if max(int(t.points.max()) for t in doc.tags) < 256 else 16,
            records=len(doc.tags),
            mirrors_included=False,
            imported_at=datetime.now(),
        )
        s.add(src)
        s.flush()
        for t in doc.tags:
            (blob,) = coordinates_to_blobs(t.points[None])
            r = Realization(
                order_type_id=ot_ids[t.lambda_text],
                source_id=src.id,
                record_index=t.number,
                mirrored=False,
                coordinates=blob,
                mp=t.mp,
                canonical_labeling=labelings_to_texts(np.array([t.labeling]))[0],
            )
            s.add(r)
            s.flush()
            s.add(_layout_row(r.id, t))
            s.add(
                DictionaryTag(
                    dictionary_id=d.id,
                    number=t.number,
                    order_type_id=ot_ids[t.lambda_text],
                    polarity=t.polarity,
                    realization_id=r.id,
                )
            )
    return get_dictionary(db, dict_name)


def _layout_row(realization_id: int, tag: FileTag) -> LayoutRow:
    """The stored layout of a file tag: its own triangles, figures and the placement ``import`` computes."""
    pts = tag.points[None].astype(np.float64)
    lay = layout_quality(tag.points.astype(np.float64), tag.triangles)
    maps = tag_placements(pts)
    printed = maximal_perturbations(apply_placements(maps, pts))
    return LayoutRow(
        realization_id=realization_id,
        triangles=triangles_to_text(lay.triangles),
        triangle_count=len(lay.triangles),
        min_angle_deg=float(lay.min_angle_deg),
        min_side=float(lay.min_side),
        min_gap=None if lay.min_gap is None else float(lay.min_gap),
        min_shared_gap_deg=None if lay.min_shared_gap_deg is None else float(lay.min_shared_gap_deg),
        score=float(lay.score),
        placement=json.dumps(maps[0].tolist()),
        printed_mp_unit=float(printed[0]),
    )
