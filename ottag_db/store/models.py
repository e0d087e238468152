"""SQLAlchemy 2 ORM models of the ottag database (schema changes go through migrations/)."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import (
    Boolean,
    CheckConstraint,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

__all__ = [
    "NAMING_CONVENTION",
    "Base",
    "Dictionary",
    "DictionaryTag",
    "FlipEdgeRow",
    "FlipGraphStatus",
    "LayoutRow",
    "OrderType",
    "Realization",
    "Source",
    "coordinates_from_blob",
    "coordinates_from_blobs",
    "coordinates_to_blobs",
    "labelings_to_texts",
    "triangles_from_text",
    "triangles_to_text",
]

#: Every constraint and index gets a predictable name (needed by batch migrations on SQLite).
NAMING_CONVENTION = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Base(DeclarativeBase):
    """Declarative base carrying the naming convention."""

    metadata = MetaData(naming_convention=NAMING_CONVENTION)


class Source(Base):
    """An imported point-set file (or the bundled data set)."""

    __tablename__ = "sources"
    __table_args__ = (UniqueConstraint("sha256"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    file_name: Mapped[str] = mapped_column(String(512))
    sha256: Mapped[str] = mapped_column(String(64))
    n: Mapped[int] = mapped_column(Integer)
    coordinate_bits: Mapped[int] = mapped_column(Integer)
    records: Mapped[int] = mapped_column(Integer)
    mirrors_included: Mapped[bool] = mapped_column(Boolean, default=False)
    imported_at: Mapped[datetime] = mapped_column(DateTime)

    realizations: Mapped[list[Realization]] = relationship(back_populates="source")


class OrderType(Base):
    """One order type, identified by its canonical λ-matrix (text form ``k:digits``).

    ``lambda_text`` is the ID (SQL column ``canonical_lambda``), ``mirror_lambda_text`` the
    ID of the mirror image (SQL column ``mirror_lambda``).
    """

    __tablename__ = "order_types"
    __table_args__ = (UniqueConstraint("k", "canonical_lambda"), UniqueConstraint("k", "number"))

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    k: Mapped[int] = mapped_column(Integer)
    # The attribute is the ID's one name in code; the SQL column keeps its original name.
    lambda_text: Mapped[str] = mapped_column("canonical_lambda", String(110))
    unique_min: Mapped[bool] = mapped_column(Boolean)
    minimal_orderings: Mapped[int] = mapped_column(Integer)
    hull_size: Mapped[int] = mapped_column(Integer)
    mirror_lambda_text: Mapped[str] = mapped_column("mirror_lambda", String(110))
    chiral: Mapped[bool] = mapped_column(Boolean)
    # Rank among all order types of k (both chiralities) by canonical λ; set once the
    # database holds every order type of k, so it is the same in every complete database.
    number: Mapped[int | None] = mapped_column(Integer, nullable=True)

    realizations: Mapped[list[Realization]] = relationship(back_populates="order_type")


class Realization(Base):
    """A concrete point set of an order type: a record of a source file (maybe mirrored)."""

    __tablename__ = "realizations"
    __table_args__ = (
        UniqueConstraint("source_id", "record_index", "mirrored"),
        Index("ix_realizations_order_type_id_mp", "order_type_id", "mp"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    order_type_id: Mapped[int] = mapped_column(ForeignKey("order_types.id", ondelete="CASCADE"))
    source_id: Mapped[int] = mapped_column(ForeignKey("sources.id", ondelete="CASCADE"))
    record_index: Mapped[int] = mapped_column(Integer)
    mirrored: Mapped[bool] = mapped_column(Boolean, default=False)
    # (k, 2) little-endian uint16 x, y pairs in file order.
    coordinates: Mapped[bytes] = mapped_column(LargeBinary)
    mp: Mapped[float] = mapped_column(Float)
    # One decimal digit per canonical label: digit l is the file index of label l.
    canonical_labeling: Mapped[str] = mapped_column(String(10))

    order_type: Mapped[OrderType] = relationship(back_populates="realizations")
    source: Mapped[Source] = relationship(back_populates="realizations")
    layout: Mapped[LayoutRow | None] = relationship(back_populates="realization", uselist=False)

    def points(self) -> NDArray[np.int64]:
        """Coordinates as a ``(k, 2)`` int64 array in file order."""
        return coordinates_from_blob(self.coordinates)

    def labeling(self) -> tuple[int, ...]:
        """Canonical labeling: ``labeling[l]`` is the file index of the point with label ``l``."""
        return tuple(int(c) for c in self.canonical_labeling)

    def canonical_points(self) -> NDArray[np.int64]:
        """Coordinates in canonical label order (row ``l`` = point with label ``l``)."""
        return self.points()[list(self.labeling())]


class LayoutRow(Base):
    """The triangles drawn for a realization, their quality figures and the tag placement.

    ``triangles`` is ``"a,b,c;d,e,f"`` (file indices); ``placement`` the JSON ``(2, 3)``
    affine map from file coordinates to data-area unit coordinates (x right, y down);
    ``printed_mp_unit`` the MP after placement in units of the data-area side.
    """

    __tablename__ = "layouts"
    __table_args__ = (UniqueConstraint("realization_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    realization_id: Mapped[int] = mapped_column(ForeignKey("realizations.id", ondelete="CASCADE"))
    triangles: Mapped[str] = mapped_column(String(200))
    triangle_count: Mapped[int] = mapped_column(Integer)
    min_angle_deg: Mapped[float] = mapped_column(Float)
    min_side: Mapped[float] = mapped_column(Float)
    min_gap: Mapped[float | None] = mapped_column(Float, nullable=True)
    min_shared_gap_deg: Mapped[float | None] = mapped_column(Float, nullable=True)
    score: Mapped[float] = mapped_column(Float)
    placement: Mapped[str] = mapped_column(String(400))
    printed_mp_unit: Mapped[float] = mapped_column(Float)

    realization: Mapped[Realization] = relationship(back_populates="layout")

    def triangle_list(self) -> list[tuple[int, int, int]]:
        """Triangles as index triples into the realization's file-order points."""
        return list(triangles_from_text(self.triangles))


class FlipEdgeRow(Base):
    """Two order types one triple-flip apart; ``triple`` = canonical labels ``a,b,c`` of the source."""

    __tablename__ = "flip_edges"
    __table_args__ = (Index("ix_flip_edges_target_id", "target_id"),)

    source_id: Mapped[int] = mapped_column(ForeignKey("order_types.id", ondelete="CASCADE"), primary_key=True)
    target_id: Mapped[int] = mapped_column(ForeignKey("order_types.id", ondelete="CASCADE"), primary_key=True)
    triple: Mapped[str] = mapped_column(String(8), primary_key=True)


class FlipGraphStatus(Base):
    """For which k the flip graph was computed (over how many order types)."""

    __tablename__ = "flip_graph_status"

    k: Mapped[int] = mapped_column(Integer, primary_key=True)
    order_types: Mapped[int] = mapped_column(Integer)
    edges: Mapped[int] = mapped_column(Integer)
    computed_at: Mapped[datetime] = mapped_column(DateTime)


class Dictionary(Base):
    """A named tag dictionary; ``parameters`` is the JSON of the options it was made with."""

    __tablename__ = "dictionaries"
    __table_args__ = (UniqueConstraint("name"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(100))
    min_flip_distance: Mapped[int] = mapped_column(Integer)
    parameters: Mapped[str] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(DateTime)

    tags: Mapped[list[DictionaryTag]] = relationship(
        back_populates="dictionary", order_by="DictionaryTag.number", cascade="all, delete-orphan"
    )


class DictionaryTag(Base):
    """Member ``number`` (0 … N−1) of a dictionary: an order type in one polarity.

    ``realization_id`` is the geometry the member is printed from and verified against (set by
    ``dictionary create`` and ``dictionary import``; NULL in dictionaries made before revision
    0005, which use the order type's best realization and verify against all of them).
    """

    __tablename__ = "dictionary_tags"
    __table_args__ = (
        UniqueConstraint("dictionary_id", "order_type_id", "polarity"),
        CheckConstraint("polarity IN ('normal', 'inverted')", name="polarity"),
    )

    dictionary_id: Mapped[int] = mapped_column(ForeignKey("dictionaries.id", ondelete="CASCADE"), primary_key=True)
    number: Mapped[int] = mapped_column(Integer, primary_key=True)
    order_type_id: Mapped[int] = mapped_column(ForeignKey("order_types.id", ondelete="CASCADE"))
    polarity: Mapped[str] = mapped_column(String(10))
    realization_id: Mapped[int | None] = mapped_column(
        ForeignKey("realizations.id", ondelete="SET NULL"), nullable=True, default=None
    )

    dictionary: Mapped[Dictionary] = relationship(back_populates="tags")
    order_type: Mapped[OrderType] = relationship()


def coordinates_to_blobs(points: NDArray[np.integer]) -> list[bytes]:
    """Blobs of the ``coordinates`` column.

    Parameters
    ----------
    points : ndarray
        ``(B, k, 2)`` non-negative integer coordinates below 65536.

    Returns
    -------
    list of bytes
        One little-endian uint16 ``x, y`` blob per set, in file order.
    """
    arr = np.ascontiguousarray(np.asarray(points), dtype="<u2")
    size = arr.shape[1] * 4
    raw = arr.tobytes()
    return [raw[i * size : (i + 1) * size] for i in range(arr.shape[0])]


def coordinates_from_blob(blob: bytes) -> NDArray[np.int64]:
    """Coordinates of one blob of the ``coordinates`` column.

    Parameters
    ----------
    blob : bytes
        Little-endian uint16 ``x, y`` pairs.

    Returns
    -------
    ndarray
        ``(k, 2)`` int64 coordinates in file order.
    """
    return np.frombuffer(blob, dtype="<u2").reshape(-1, 2).astype(np.int64)


def coordinates_from_blobs(blobs: Sequence[bytes], k: int) -> NDArray[np.int64]:
    """Coordinates of many blobs of the ``coordinates`` column at once.

    Parameters
    ----------
    blobs : sequence of bytes
        Little-endian uint16 ``x, y`` pairs, ``k`` points each.
    k : int
        Points per set.

    Returns
    -------
    ndarray
        ``(len(blobs), k, 2)`` int64 coordinates in file order.
    """
    return np.frombuffer(b"".join(blobs), dtype="<u2").reshape(len(blobs), k, 2).astype(np.int64)


def triangles_to_text(triangles: Sequence[Sequence[int]]) -> str:
    """Value of the ``layouts.triangles`` column (inverse of :func:`triangles_from_text`).

    Parameters
    ----------
    triangles : sequence of (int, int, int)
        File indices of each triangle's vertices.

    Returns
    -------
    str
        ``"a,b,c;d,e,f"``.
    """
    return ";".join(",".join(str(i) for i in t) for t in triangles)


def triangles_from_text(text: str) -> tuple[tuple[int, int, int], ...]:
    """Triangles of one value of the ``layouts.triangles`` column.

    Parameters
    ----------
    text : str
        ``"a,b,c;d,e,f"``: file indices of each triangle's vertices.

    Returns
    -------
    tuple of (int, int, int)
        One index triple per triangle, in stored order.
    """
    out = []
    for t in text.split(";"):
        a, b, c = (int(v) for v in t.split(","))
        out.append((a, b, c))
    return tuple(out)


def labelings_to_texts(labelings: NDArray[np.integer]) -> list[str]:
    """Texts of the ``canonical_labeling`` column.

    Parameters
    ----------
    labelings : ndarray
        ``(B, k)`` labelings, ``labeling[l]`` = file index of the point with label ``l``.

    Returns
    -------
    list of str
        One digit string per set (digit ``l`` is ``labeling[l]``).
    """
    arr = np.asarray(labelings)
    k = arr.shape[1]
    raw = (arr.astype(np.uint8) + ord("0")).tobytes()
    return [raw[i * k : (i + 1) * k].decode("ascii") for i in range(arr.shape[0])]
