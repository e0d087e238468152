"""Dictionary files: export a stored dictionary as JSON or CSV, import one from its JSON export."""

from __future__ import annotations

import csv
import io
import json
from datetime import datetime

from sqlalchemy import select

from ottag_db.core.canonical import lambda_text, parse_lambda_text
from ottag_db.errors import DictionaryError, UsageError
from ottag_db.store.db import Database
from ottag_db.store.dictionaries import DictionaryInfo, check_dictionary_name, get_dictionary
from ottag_db.store.models import Dictionary, DictionaryTag, OrderType

__all__ = ["export_dictionary", "import_dictionary"]


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
                "format": "ottag-dictionary/1",
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


def import_dictionary(db: Database, text: str, *, source: str = "<input>", name: str | None = None) -> DictionaryInfo:
    """Store a dictionary from its JSON export; every member's order type must be in the database.

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
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DictionaryError(f"{source}: not JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})") from exc
    if not isinstance(data, dict) or "tags" not in data or "name" not in data:
        raise DictionaryError(f"{source}: not an ottag dictionary export (needs 'name' and 'tags')")
    dict_name = name or str(data["name"])
    check_dictionary_name(dict_name)
    tags = data["tags"]
    if not isinstance(tags, list) or not tags:
        raise DictionaryError(f"{source}: 'tags' must be a non-empty list")
    with db.session() as s:
        if s.execute(select(Dictionary.id).where(Dictionary.name == dict_name)).first() is not None:
            raise DictionaryError(f"a dictionary named {dict_name!r} exists already; delete it or pass --name")
        d = Dictionary(
            name=dict_name,
            min_flip_distance=int(data.get("min_flip_distance", 1)),
            parameters=json.dumps(data.get("parameters", {}), sort_keys=True),
            created_at=datetime.now(),
        )
        s.add(d)
        s.flush()
        seen: set[int] = set()
        for i, tag in enumerate(tags):
            try:
                number = int(tag["number"])
                polarity = str(tag.get("polarity", "normal"))
                mat = parse_lambda_text(str(tag["lambda"]))
            except (KeyError, TypeError, ValueError) as exc:
                raise DictionaryError(f"{source}: tag {i}: needs 'number', 'lambda' and 'polarity' ({exc})") from exc
            if polarity not in ("normal", "inverted"):
                raise DictionaryError(f"{source}: tag {i}: polarity must be normal or inverted")
            if number in seen:
                raise DictionaryError(f"{source}: tag {i}: number {number} appears twice")
            seen.add(number)
            text_id = lambda_text(mat)
            ot_id = s.execute(
                select(OrderType.id).where(OrderType.k == mat.shape[0], OrderType.lambda_text == text_id)
            ).scalar_one_or_none()
            if ot_id is None:
                raise DictionaryError(
                    f"{source}: tag {number}: order type {text_id} is not in the database; "
                    "import the bundled data first"
                )
            s.add(DictionaryTag(dictionary_id=d.id, number=number, order_type_id=ot_id, polarity=polarity))
    return get_dictionary(db, dict_name)
