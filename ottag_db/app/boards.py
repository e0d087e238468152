"""Calibration boards: choose the tags, draw the page, and the ``.board.json`` that describes it.

The board file (format ``ottag-board/1``) holds everything calibration needs, so
``ottag-db calibrate`` works without a database::

    {"format": "ottag-board/1", "tag_size_mm", "spacing_mm", "rows", "cols", "k",
     "page_mm": [w, h], "page_origin_mm": [x, y], "dictionary": name | null,
     "tags": [{"row", "col", "lambda", "number", "polarity", "corners_mm": 4×[x, y],
               "points_mm": k×[x, y], "triangles": [[a, b, c], …]}]}

Board coordinates are mm, origin at the top-left corner of the first tag's data area, x right,
y down, z = 0. ``corners_mm``: data-area corners top-left, top-right, bottom-right,
bottom-left; ``points_mm``: the tag's points in canonical label order (the order ``decode``
reports); ``triangles``: the printed triangles as label triples (optional; calibration fits the
printed edges with them). ``number`` is the universal number (null when not numbered); ``page_origin_mm``
the board origin on the printed page (from the page's top-left corner).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ottag_db.app.export import short_id, tag_geometries
from ottag_db.core.canonical import canonical_form
from ottag_db.core.lookup import LookupEntry, MemoryLookup
from ottag_db.core.types import POLARITIES, ProgressCallback
from ottag_db.errors import BoardError, ExportError, GeneralPositionError, UsageError
from ottag_db.printing.board import BoardPlacement, board_page, write_board_pdf
from ottag_db.printing.sheet import parse_length, parse_page
from ottag_db.store.db import Database
from ottag_db.store.dictionaries import dictionary_tag_records
from ottag_db.store.flipgraph import ensure_flip_graph, flip_adjacency, within_flips
from ottag_db.store.queries import order_type_numbers
from ottag_db.store.tags import TagRecord, select_tags

__all__ = [
    "BOARD_FORMAT",
    "Board",
    "BoardTag",
    "board_lookup",
    "board_path_for",
    "create_board",
    "read_board",
    "write_board",
]

#: The ``format`` value of a board file.
BOARD_FORMAT = "ottag-board/1"

_F64 = NDArray[np.float64]


@dataclass(frozen=True)
class BoardTag:
    """One tag of a board: grid cell, ID, universal number, polarity and board positions (mm)."""

    row: int
    col: int
    lambda_text: str
    number: int | None
    polarity: str
    corners_mm: tuple[tuple[float, float], ...]
    points_mm: tuple[tuple[float, float], ...]
    triangles: tuple[tuple[int, int, int], ...] = ()

    @property
    def k(self) -> int:
        """Number of points."""
        return len(self.points_mm)

    def as_json(self) -> dict[str, Any]:
        """The tag's object in the board file."""
        return {
            "row": self.row,
            "col": self.col,
            "lambda": self.lambda_text,
            "number": self.number,
            "polarity": self.polarity,
            "corners_mm": [[round(x, 6), round(y, 6)] for x, y in self.corners_mm],
            "points_mm": [[round(x, 6), round(y, 6)] for x, y in self.points_mm],
            "triangles": [list(t) for t in self.triangles],
        }


@dataclass(frozen=True)
class Board:
    """A calibration board: grid, sizes (mm), where it sits on the page, and its tags."""

    tag_size_mm: float
    spacing_mm: float
    rows: int
    cols: int
    tags: tuple[BoardTag, ...]
    page_mm: tuple[float, float] | None = None
    page_origin_mm: tuple[float, float] | None = None
    dictionary: str | None = None

    @property
    def ks(self) -> tuple[int, ...]:
        """Point counts on the board, ascending."""
        return tuple(sorted({t.k for t in self.tags}))

    @property
    def size_mm(self) -> tuple[float, float]:
        """Width and height of the grid of data areas, mm."""
        return (
            self.cols * self.tag_size_mm + (self.cols - 1) * self.spacing_mm,
            self.rows * self.tag_size_mm + (self.rows - 1) * self.spacing_mm,
        )

    def object_points(self, index: int) -> _F64:
        """``(k + 4, 3)`` board coordinates (mm, z = 0) of tag ``index``: points, then corners."""
        t = self.tags[index]
        xy = np.array(t.points_mm + t.corners_mm, dtype=np.float64)
        out: _F64 = np.c_[xy, np.zeros(len(xy))]
        return out

    def as_json(self) -> dict[str, Any]:
        """The board file's content."""
        return {
            "format": BOARD_FORMAT,
            "tag_size_mm": self.tag_size_mm,
            "spacing_mm": self.spacing_mm,
            "rows": self.rows,
            "cols": self.cols,
            "k": self.ks[0] if len(self.ks) == 1 else list(self.ks),
            "page_mm": None if self.page_mm is None else [round(v, 6) for v in self.page_mm],
            "page_origin_mm": None if self.page_origin_mm is None else [round(v, 6) for v in self.page_origin_mm],
            "dictionary": self.dictionary,
            "tags": [t.as_json() for t in self.tags],
        }


def board_path_for(pdf: str | os.PathLike[str]) -> Path:
    """The board file written beside ``pdf``: ``OUT.pdf`` → ``OUT.board.json``.

    Parameters
    ----------
    pdf : str or PathLike
        The board's PDF.

    Returns
    -------
    Path
        Same folder and stem, suffix ``.board.json``.
    """
    p = Path(pdf)
    return p.with_name(p.stem + ".board.json") if p.suffix.lower() == ".pdf" else p.with_name(p.name + ".board.json")


def _default_tags(db: Database, k: int, count: int, progress: ProgressCallback | None) -> list[TagRecord]:
    """The ``count`` highest-MP members of a flip-distance-2 set of ``k``-point unique-minimum tags.

    The greedy order is the one of ``dictionary create`` (MP descending, then canonical λ), so
    these are the first ``count`` tags of ``dictionary create NAME --k K --matchable``.
    """
    candidates = select_tags(db, ks=[k], matchable=True)
    if not candidates:
        raise ExportError(f"the database has no drawable {k}-point tags: run `ottag-db import` first")
    ensure_flip_graph(db, [k], progress=progress)
    adj = flip_adjacency(db, [k])
    candidates.sort(key=lambda t: (-t.mp, t.k, t.lambda_text))
    chosen: list[TagRecord] = []
    blocked: set[int] = set()
    for t in candidates:
        if len(chosen) == count:
            break
        if t.order_type_id in blocked:
            continue
        chosen.append(t)
        blocked |= within_flips(adj, t.order_type_id, 1)
    if len(chosen) < count:
        raise ExportError(
            f"a flip-distance-2 set of {k}-point tags holds only {len(chosen)} tags; the board needs {count}: "
            "use fewer rows/columns or another --k"
        )
    return chosen


def _dictionary_tags(db: Database, name: str, count: int) -> tuple[list[TagRecord], list[str]]:
    """The first ``count`` unique-minimum members of dictionary ``name`` and their polarities."""
    info, records = dictionary_tag_records(db, name)
    usable = [(m, t) for m, t in zip(info.members, records, strict=True) if m.unique_min and m.k != 4]
    if len(usable) < count:
        raise ExportError(
            f"dictionary {name} has {len(usable)} tags with unambiguous point labels (unique minimum); "
            f"the board needs {count}: use fewer rows/columns or a larger dictionary"
        )
    chosen = usable[:count]  # each member's own realization (the one the decoder verifies against)
    return [t for _, t in chosen], [m.polarity for m, _ in chosen]


def create_board(
    db: Database,
    out: str | os.PathLike[str],
    *,
    rows: int,
    cols: int,
    tag_size_mm: float | str,
    spacing_mm: float | str,
    page: str | tuple[float, float] = "A4",
    k: int = 8,
    dictionary: str | None = None,
    progress: ProgressCallback | None = None,
) -> tuple[Board, Path]:
    """Write a calibration board: ``out`` (one-page PDF) and ``OUT.board.json`` beside it.

    Tags are distinct order types with a unique minimal ordering (unambiguous point labels),
    filled row by row from the top left: by default the highest-MP members of a flip-distance-2
    set of ``k``-point tags (the flip graph of ``k`` is computed and stored once, as
    ``dictionary create`` does); with ``dictionary`` its first unique-minimum members in number
    order, each in its own polarity. Each tag is drawn from its stored layout and placement.

    Parameters
    ----------
    db : Database
        An open database with the order types of ``k`` imported.
    out : str or PathLike
        The PDF file.
    rows, cols : int
        Grid size.
    tag_size_mm, spacing_mm : float or str
        Data-area side and the paper between neighbouring data areas: mm, or a length with
        a unit (``"40mm"``, see :func:`ottag_db.printing.sheet.parse_length`).
    page : str or tuple of float
        Page name or size text (see :func:`ottag_db.printing.sheet.parse_page`) or ``(w, h)`` mm.
    k : int
        Point count of the default tags (ignored with ``dictionary``).
    dictionary : str, optional
        Take the tags from this dictionary.
    progress : ProgressCallback, optional
        Progress of computing the flip graph of ``k``, when it is not stored yet.

    Returns
    -------
    tuple of (Board, Path)
        The board and the path of its board file.

    Raises
    ------
    UsageError
        Bad sizes, page or k.
    ExportError
        The board does not fit the page (the message names the largest grid that does), too
        few tags, or a file cannot be written.
    NotFoundError
        No dictionary of that name.
    """
    if dictionary is None and k not in (3, 5, 6, 7, 8):
        raise UsageError(f"--k must be 3, 5, 6, 7 or 8 (4-point order types cannot be drawn), got {k}")
    tag_size_mm = parse_length(tag_size_mm) if isinstance(tag_size_mm, str) else float(tag_size_mm)
    spacing_mm = parse_length(spacing_mm) if isinstance(spacing_mm, str) else float(spacing_mm)
    page_mm = parse_page(page) if isinstance(page, str) else (float(page[0]), float(page[1]))
    layout = board_page(page_mm, rows, cols, tag_size_mm, spacing_mm)
    count = rows * cols
    if dictionary is None:
        records = _default_tags(db, k, count, progress)
        polarities = ["normal"] * count
        summary = f"{count} distinct {k}-point tags, no two one flip apart (highest MP first)"
    else:
        records, polarities = _dictionary_tags(db, dictionary, count)
        summary = f"the first {count} unique-minimum tags of dictionary {dictionary}"
    numbers = order_type_numbers(db)
    geoms = tag_geometries(records, "normal", tag_size_mm)
    tags: list[BoardTag] = []
    placements: list[BoardPlacement] = []
    for i, (rec, geom, pol) in enumerate(zip(records, geoms, polarities, strict=True)):
        row, col = divmod(i, cols)
        x0, y0 = layout.data_area_mm(row, col)
        unit = geom.points_array[list(rec.labeling)]  # canonical label order
        pts = np.c_[x0 + tag_size_mm * unit[:, 0], y0 + tag_size_mm * unit[:, 1]]
        s = tag_size_mm
        corners = ((x0, y0), (x0 + s, y0), (x0 + s, y0 + s), (x0, y0 + s))
        number = numbers.get(rec.order_type_id)
        label_of = {g: lab for lab, g in enumerate(rec.labeling)}
        tags.append(
            BoardTag(
                row=row,
                col=col,
                lambda_text=rec.lambda_text,
                number=number,
                polarity=pol,
                corners_mm=tuple((float(a), float(b)) for a, b in corners),
                points_mm=tuple((float(a), float(b)) for a, b in pts),
                triangles=tuple((label_of[a], label_of[b], label_of[c]) for a, b, c in geom.triangles),
            )
        )
        label = f"r{row} c{col}  {short_id(rec.lambda_text)}" + (f"  #{number}" if number is not None else "")
        placements.append(BoardPlacement(row, col, geom.with_polarity(pol), label))  # type: ignore[arg-type]
    board = Board(
        tag_size_mm=float(tag_size_mm),
        spacing_mm=float(spacing_mm),
        rows=rows,
        cols=cols,
        tags=tuple(tags),
        page_mm=layout.page_mm,
        page_origin_mm=layout.origin_mm,
        dictionary=dictionary,
    )
    board_file = board_path_for(out)
    write_board_pdf(
        out,
        layout,
        placements,
        summary=f"{rows} × {cols} board: {summary}. Geometry: {board_file.name}",
    )
    write_board(board, board_file)
    return board, board_file


def write_board(board: Board, path: str | os.PathLike[str]) -> None:
    """Write the board file (JSON, see the module docstring).

    Parameters
    ----------
    board : Board
        The board.
    path : str or PathLike
        The ``.board.json`` file.

    Raises
    ------
    ExportError
        The file cannot be written.
    """
    p = Path(path)
    try:
        data = board.as_json()
        tags = data.pop("tags")
        head = json.dumps(data, indent=1)[:-2]  # without the closing "\n}"
        body = ",\n".join("  " + json.dumps(t) for t in tags)
        p.write_text(f'{head},\n "tags": [\n{body}\n ]\n}}\n', encoding="utf-8")
    except OSError as exc:
        raise ExportError(f"cannot write the board file {p}: {exc.strerror or exc}") from exc


def _xy_list(value: Any, n: int | None, what: str) -> tuple[tuple[float, float], ...]:
    if not isinstance(value, list) or (n is not None and len(value) != n):
        raise ValueError(f"{what} must be a list of {n if n is not None else 'k'} [x, y] pairs")
    out = []
    for p in value:
        if not (isinstance(p, list) and len(p) == 2 and all(isinstance(v, (int, float)) for v in p)):
            raise ValueError(f"{what} must hold [x, y] number pairs")
        x, y = float(p[0]), float(p[1])
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"{what} holds a non-finite number")
        out.append((x, y))
    return tuple(out)


def _triangles(value: Any, k: int) -> tuple[tuple[int, int, int], ...]:
    if isinstance(value, list) and all(isinstance(t, list) and len(t) == 3 and set(t) <= set(range(k)) for t in value):
        return tuple((int(t[0]), int(t[1]), int(t[2])) for t in value)
    raise ValueError(f"triangles must be a list of [a, b, c] point labels 0 … {k - 1}")


def _parse_tag(i: int, raw: Any) -> BoardTag:
    if not isinstance(raw, dict):
        raise ValueError("is not an object")
    for key in ("row", "col", "lambda", "polarity", "corners_mm", "points_mm"):
        if key not in raw:
            raise ValueError(f"has no {key!r}")
    if raw["polarity"] not in POLARITIES:
        raise ValueError(f"polarity must be normal or inverted, got {raw['polarity']!r}")
    points = _xy_list(raw["points_mm"], None, "points_mm")
    if not 3 <= len(points) <= 9:
        raise ValueError(f"has {len(points)} points; a tag has 3 … 9")
    tag = BoardTag(
        row=int(raw["row"]),
        col=int(raw["col"]),
        lambda_text=str(raw["lambda"]),
        number=None if raw.get("number") is None else int(raw["number"]),
        polarity=str(raw["polarity"]),
        corners_mm=_xy_list(raw["corners_mm"], 4, "corners_mm"),
        points_mm=points,
        triangles=_triangles(raw.get("triangles", []), len(points)),
    )
    try:
        form = canonical_form(np.array(points))
    except GeneralPositionError as exc:
        raise ValueError(f"points_mm are not in general position ({exc})") from exc
    if form.text != tag.lambda_text:
        raise ValueError(f"points_mm have the order type {form.text}, not the stated lambda")
    if not form.unique_min or form.labeling != tuple(range(tag.k)):
        raise ValueError("points_mm are not in canonical label order with a unique minimum")
    return tag


def read_board(path: str | os.PathLike[str]) -> Board:
    """Read and check a board file: format, sizes, and every tag's points against its ID.

    Parameters
    ----------
    path : str or PathLike
        A ``.board.json`` file written by ``ottag-db board create``.

    Returns
    -------
    Board
        The board.

    Raises
    ------
    BoardError
        A missing or unreadable file, another format, or a tag whose points do not have its
        order type in canonical label order; the message names the file and the record.
    """
    p = Path(path)
    if not p.is_file():
        raise BoardError(f"{p}: board file not found (create one with `ottag-db board create OUT.pdf`)")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BoardError(
            f"{p}: not a JSON board file ({exc}); pass the OUT.board.json written by `board create`"
        ) from exc
    fmt = data.get("format") if isinstance(data, dict) else None
    if fmt != BOARD_FORMAT:
        raise BoardError(
            f"{p}: not an {BOARD_FORMAT} board file (format {fmt!r}); pass the OUT.board.json written by `board create`"
        )
    try:
        size, spacing = float(data["tag_size_mm"]), float(data.get("spacing_mm", 0.0))
        rows, cols = int(data["rows"]), int(data["cols"])
        raw_tags = data["tags"]
        if not (size > 0 and rows >= 1 and cols >= 1 and isinstance(raw_tags, list) and raw_tags):
            raise ValueError("needs tag_size_mm > 0, rows, cols ≥ 1 and a non-empty tags list")
        page = data.get("page_mm")
        origin = data.get("page_origin_mm")
    except (KeyError, TypeError, ValueError) as exc:
        raise BoardError(f"{p}: malformed board file ({exc})") from exc
    tags = []
    for i, raw in enumerate(raw_tags):
        try:
            tags.append(_parse_tag(i, raw))
        except (TypeError, ValueError) as exc:
            raise BoardError(f"{p}: tag {i} {exc}; re-create the board file with `ottag-db board create`") from exc
    try:
        page_mm = None if page is None else (float(page[0]), float(page[1]))
        origin_mm = None if origin is None else (float(origin[0]), float(origin[1]))
        return Board(size, spacing, rows, cols, tuple(tags), page_mm, origin_mm, data.get("dictionary"))
    except (TypeError, ValueError, IndexError) as exc:
        raise BoardError(f"{p}: malformed page_mm or page_origin_mm ({exc})") from exc


def board_lookup(board: Board) -> MemoryLookup:
    """A decoder lookup holding only the board's tags (no database needed).

    Each entry's realization is the tag's points in its own data-area frame (mm from the
    data area's top-left corner, canonical label order), so a detection's homography maps that
    frame to the image and its corners come in the printed order top-left … bottom-left.
    ``Detection.tag`` is the index of the tag in ``board.tags`` (per polarity, when the same
    order type is on the board twice).

    Parameters
    ----------
    board : Board
        The board.

    Returns
    -------
    MemoryLookup
        One entry per order type on the board.

    Raises
    ------
    BoardError
        The same order type twice in one polarity (the correspondences would be ambiguous).
    """
    groups: dict[str, dict[str, int]] = {}
    for i, t in enumerate(board.tags):
        pols = groups.setdefault(t.lambda_text, {})
        if t.polarity in pols:
            raise BoardError(f"tags {pols[t.polarity]} and {i} of the board have the same ID and polarity")
        pols[t.polarity] = i
    entries = []
    for text, pols in groups.items():
        first = board.tags[min(pols.values())]
        local = np.array(first.points_mm) - np.array(first.corners_mm[0])
        entries.append(
            LookupEntry(
                lambda_text=text,
                k=first.k,
                order_type_id=min(pols.values()),
                unique_min=True,
                realizations=(local,),
                tag=min(pols.values()),
                extra={"tags": dict(pols)},
            )
        )
    return MemoryLookup(entries)
