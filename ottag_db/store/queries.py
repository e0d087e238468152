"""Read-side queries: statistics (paper Tables 2, 3, 7), listings, details and ad-hoc IDs."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session

from ottag_db.core.canonical import canonical_form, lambda_text, parse_lambda_text
from ottag_db.core.geometry import check_general_position, maximal_perturbation
from ottag_db.errors import GeneralPositionError, NotFoundError, UsageError
from ottag_db.store.db import Database
from ottag_db.store.models import OrderType, Realization, coordinates_from_blob
from ottag_db.store.statistics import KStats, best_mp_query, database_stats

__all__ = [
    "IdResult",
    "KStats",
    "OrderTypeDetail",
    "OrderTypeSummary",
    "RealizationInfo",
    "database_stats",
    "find_order_type",
    "get_order_type",
    "identify_points",
    "list_order_types",
    "order_type_numbers",
    "parse_points",
]


@dataclass(frozen=True)
class OrderTypeSummary:
    """One order type with its best (largest-MP) realization; ``points`` in file order."""

    id: int
    k: int
    lambda_text: str
    mp: float
    points: list[list[int]]
    hull_size: int
    unique_min: bool
    minimal_orderings: int
    chiral: bool
    mirror: str
    realizations: int
    number: int | None = None

    def as_json(self) -> dict[str, object]:
        """The machine-readable contract of ``list --format json``."""
        return {
            "id": self.id,
            "number": self.number,
            "k": self.k,
            "lambda": self.lambda_text,
            "mp": self.mp,
            "points": self.points,
            "hull_size": self.hull_size,
            "unique_min": self.unique_min,
            "minimal_orderings": self.minimal_orderings,
            "chiral": self.chiral,
            "mirror": self.mirror,
            "realizations": self.realizations,
        }


@dataclass(frozen=True)
class RealizationInfo:
    """One stored realization: its source file, record, coordinates (file order), MP, labeling."""

    id: int
    source: str
    record_index: int
    mirrored: bool
    points: list[list[int]]
    mp: float
    labeling: tuple[int, ...]


@dataclass(frozen=True)
class OrderTypeDetail:
    """Everything ``show`` prints: the summary, the λ-matrix and all realizations (best first)."""

    summary: OrderTypeSummary
    lambda_matrix: NDArray[np.int8]
    mirror_id: int | None
    realizations: list[RealizationInfo]


@dataclass(frozen=True)
class IdResult:
    """Canonical ID of an ad-hoc point set and whether the database holds it."""

    lambda_text: str
    k: int
    unique_min: bool
    minimal_orderings: int
    hull_size: int
    mp: float
    labeling: tuple[int, ...]
    in_database: bool
    id: int | None
    number: int | None = None

    def as_json(self) -> dict[str, object]:
        """The machine-readable contract of ``id --json``."""
        return {
            "lambda": self.lambda_text,
            "k": self.k,
            "unique_min": self.unique_min,
            "in_database": self.in_database,
            "id": self.id,
            "number": self.number,
            "minimal_orderings": self.minimal_orderings,
            "hull_size": self.hull_size,
            "mp": self.mp,
            "labeling": list(self.labeling),
        }


def list_order_types(
    db: Database,
    *,
    ks: Sequence[int] = (),
    min_mp: float | None = None,
    matchable: bool = False,
    ids: Sequence[int] = (),
    lambdas: Sequence[str] = (),
) -> list[OrderTypeSummary]:
    """Order types with their best realization, ordered by k then canonical λ (deterministic).

    Parameters
    ----------
    db : Database
        An open database (only read).
    ks : sequence of int
        Only these point counts (empty: all).
    min_mp : float, optional
        Only order types whose best realization has MP ≥ ``min_mp`` (grid units).
    matchable : bool
        Only order types with a unique minimal ordering.
    ids : sequence of int
        Only these database ids.
    lambdas : sequence of str
        Only these canonical IDs.

    Returns
    -------
    list of OrderTypeSummary
        The contract of ``list --format json``.
    """
    best = best_mp_query().subquery()
    q = (
        select(OrderType, best.c.mp, best.c.n)
        .join(best, best.c.order_type_id == OrderType.id)
        .order_by(OrderType.k, OrderType.lambda_text)
    )
    if ks:
        q = q.where(OrderType.k.in_(list(ks)))
    if min_mp is not None:
        q = q.where(best.c.mp >= min_mp)
    if matchable:
        q = q.where(OrderType.unique_min.is_(True))
    if ids:
        q = q.where(OrderType.id.in_(list(ids)))
    if lambdas:
        q = q.where(OrderType.lambda_text.in_(list(lambdas)))
    with db.session() as s:
        rows = s.execute(q).all()
        best_points = _best_realization_points(s, [r[0].id for r in rows])
    return [
        OrderTypeSummary(
            id=ot.id,
            k=ot.k,
            lambda_text=ot.lambda_text,
            mp=float(mp),
            points=best_points[ot.id],
            hull_size=ot.hull_size,
            unique_min=bool(ot.unique_min),
            minimal_orderings=ot.minimal_orderings,
            chiral=bool(ot.chiral),
            mirror=ot.mirror_lambda_text,
            realizations=int(n),
            number=ot.number,
        )
        for ot, mp, n in rows
    ]


def _best_realization_points(s: Session, order_type_ids: list[int]) -> dict[int, list[list[int]]]:
    out: dict[int, list[list[int]]] = {}
    chunk = 5000
    for i in range(0, len(order_type_ids), chunk):
        part = order_type_ids[i : i + chunk]
        rows = s.execute(
            select(Realization.order_type_id, Realization.coordinates, Realization.mp, Realization.id)
            .where(Realization.order_type_id.in_(part))
            .order_by(Realization.order_type_id, Realization.mp.desc(), Realization.id)
        ).all()
        for ot_id, blob, _mp, _rid in rows:
            if ot_id not in out:
                out[ot_id] = coordinates_from_blob(blob).tolist()
    return out


def find_order_type(s: Session, ident: str | int) -> OrderType | None:
    """The order type with database id ``ident`` (int or digits) or canonical text ``k:digits``.

    Parameters
    ----------
    s : Session
        An open session.
    ident : str or int
        Database id, or an ID in text form (any labeling; it is canonicalised first).

    Returns
    -------
    OrderType or None
        The stored row, None when the database does not hold it.
    """
    if isinstance(ident, int) or str(ident).strip().isdigit():
        return s.get(OrderType, int(ident))
    mat = parse_lambda_text(str(ident))
    return s.execute(
        select(OrderType).where(OrderType.k == mat.shape[0], OrderType.lambda_text == lambda_text(mat))
    ).scalar_one_or_none()


def get_order_type(db: Database, ident: str | int) -> OrderTypeDetail:
    """Look an order type up by database id (int or digits) or canonical text ``k:digits``.

    Parameters
    ----------
    db : Database
        An open database.
    ident : str or int
        Database id or ID text, as :func:`find_order_type`.

    Returns
    -------
    OrderTypeDetail
        Summary, λ-matrix, the mirror's database id and every realization (best first).

    Raises
    ------
    NotFoundError
        The database does not hold it (or it has no realization).
    """
    with db.session() as s:
        ot = find_order_type(s, ident)
        if ot is None:
            if isinstance(ident, int) or str(ident).strip().isdigit():
                raise NotFoundError(f"no order type with id {ident} in the database")
            raise NotFoundError(f"order type {lambda_text(parse_lambda_text(str(ident)))} is not in the database")
        mirror_id = s.execute(
            select(OrderType.id).where(OrderType.k == ot.k, OrderType.lambda_text == ot.mirror_lambda_text)
        ).scalar_one_or_none()
        reals = sorted(ot.realizations, key=lambda r: (-r.mp, r.id))
        infos = [
            RealizationInfo(
                id=r.id,
                source=r.source.file_name,
                record_index=r.record_index,
                mirrored=bool(r.mirrored),
                points=r.points().tolist(),
                mp=float(r.mp),
                labeling=r.labeling(),
            )
            for r in reals
        ]
        if not infos:
            raise NotFoundError(f"order type {ot.lambda_text} has no realization")
        summary = OrderTypeSummary(
            id=ot.id,
            k=ot.k,
            lambda_text=ot.lambda_text,
            mp=infos[0].mp,
            points=infos[0].points,
            hull_size=ot.hull_size,
            unique_min=bool(ot.unique_min),
            minimal_orderings=ot.minimal_orderings,
            chiral=bool(ot.chiral),
            mirror=ot.mirror_lambda_text,
            realizations=len(infos),
            number=ot.number,
        )
    return OrderTypeDetail(
        summary=summary, lambda_matrix=parse_lambda_text(summary.lambda_text), mirror_id=mirror_id, realizations=infos
    )


def parse_points(text: str) -> NDArray[np.float64]:
    """Parse a point list typed by a user.

    Parameters
    ----------
    text : str
        ``"x,y x,y …"`` (also ``;`` separated), 3 to 10 points.

    Returns
    -------
    ndarray
        ``(k, 2)`` float64 coordinates in the given order.

    Raises
    ------
    UsageError
        An unreadable or non-finite point (nan, inf, 1e400) or a count outside 3 … 10.
    """
    parts = [p for p in text.replace(";", " ").split() if p]
    pts: list[list[float]] = []
    for p in parts:
        xy = p.split(",")
        if len(xy) != 2:
            raise UsageError(f"cannot read point {p!r}: write points as x,y separated by spaces")
        try:
            xy_f = [float(xy[0]), float(xy[1])]
        except ValueError as exc:
            raise UsageError(f"cannot read point {p!r}: coordinates must be numbers") from exc
        if not all(math.isfinite(v) for v in xy_f):
            raise UsageError(f"point {len(pts)} ({p}): coordinates must be finite numbers (no nan/inf, |v| < 1.8e308)")
        pts.append(xy_f)
    if not 3 <= len(pts) <= 10:
        raise UsageError(f"a point set needs 3 to 10 points, got {len(pts)}")
    return np.array(pts, dtype=np.float64)


def identify_points(db: Database | None, points: ArrayLike) -> IdResult:
    """Canonical ID of an ad-hoc point set and its database id, if stored.

    Parameters
    ----------
    db : Database or None
        Where to look the ID up (None: do not look).
    points : array_like
        ``(k, 2)`` coordinates, screen convention (x right, y down).

    Returns
    -------
    IdResult
        ID, figures, MP (coordinate units) and the database id and number when stored.

    Raises
    ------
    GeneralPositionError
        Three points are collinear (or two coincide).
    UsageError
        Non-finite coordinates, or coordinates so far apart that their differences overflow.

    Notes
    -----
    The set is moved and scaled to a unit box first (the order type does not change), so tiny
    (1e-300) and huge (1e300) coordinates work; MP is given in the input's units.
    """
    raw = np.asarray(points, dtype=np.float64)
    if not np.isfinite(raw).all():
        raise UsageError("coordinates must be finite numbers (no nan or inf)")
    with np.errstate(over="ignore"):
        span = raw.max(axis=0) - (lo := raw.min(axis=0))
    if not np.isfinite(span).all():
        raise UsageError("the coordinates are too far apart (their differences overflow); scale the points down")
    scale = float(span.max())
    pts = (raw - lo) / scale if scale > 0 else raw
    try:
        check_general_position(pts)
    except GeneralPositionError as exc:
        raise GeneralPositionError(_unscaled(str(exc)[10:], raw, exc.points), points=exc.points) from exc
    form = canonical_form(pts)
    found: int | None = None
    number: int | None = None
    if db is not None:
        with db.session() as s:
            row = s.execute(
                select(OrderType.id, OrderType.number).where(OrderType.k == form.k, OrderType.lambda_text == form.text)
            ).first()
            if row is not None:
                found, number = int(row[0]), row[1]
    return IdResult(
        lambda_text=form.text,
        k=form.k,
        unique_min=form.unique_min,
        minimal_orderings=form.minimal_orderings,
        hull_size=form.hull_size,
        mp=maximal_perturbation(pts) * (scale if scale > 0 else 1.0),
        labeling=form.labeling,
        in_database=found is not None,
        id=found,
        number=number,
    )


def _unscaled(message: str, raw: NDArray[np.float64], indices: tuple[int, ...]) -> str:
    """The general-position message with the input's own coordinates, not the scaled ones."""
    shown = " ".join(f"{raw[i, 0]:g},{raw[i, 1]:g}" for i in indices)
    return f"{message.split(' (', 1)[0]}: {shown}" if indices else message


def order_type_numbers(db: Database) -> dict[int, int | None]:
    """Universal number of every order type.

    Parameters
    ----------
    db : Database
        An open database (only read).

    Returns
    -------
    dict of int to (int or None)
        Database id → universal number (None while its k is incomplete).
    """
    with db.session() as s:
        return {int(i): n for i, n in s.execute(select(OrderType.id, OrderType.number)).all()}


def stored_ks(db: Database) -> set[int]:
    """The point counts of which the database holds at least one order type.

    Parameters
    ----------
    db : Database
        An open database (only read).

    Returns
    -------
    set of int
        Those k.
    """
    with db.session() as s:
        return {int(k) for (k,) in s.execute(select(OrderType.k).distinct()).all()}


def missing_ks_note(db: Database, ks: Sequence[int]) -> str:
    """``"; the database has no order types of k = …"`` with how to add them, or "" when every k
    of ``ks`` is stored (for "nothing matches" messages).

    Parameters
    ----------
    db : Database
        An open database (only read).
    ks : sequence of int
        The point counts asked for.

    Returns
    -------
    str
        The note, starting with "; " (or empty).
    """
    missing = sorted(set(ks) - stored_ks(db) - {4})
    if not missing:
        return ""
    listed = ", ".join(map(str, missing))
    return (
        f"; the database has no order types of k = {listed}: import them first "
        "(`ottag-db import FILE --with-mirrors`, or `--k K` for a bundled k)"
    )
