"""Initial schema: sources, order types and realizations.

Revision ID: 0001
Revises:
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "sources",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("file_name", sa.String(512), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("n", sa.Integer(), nullable=False),
        sa.Column("coordinate_bits", sa.Integer(), nullable=False),
        sa.Column("records", sa.Integer(), nullable=False),
        sa.Column("mirrors_included", sa.Boolean(), nullable=False),
        sa.Column("imported_at", sa.DateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_sources"),
        sa.UniqueConstraint("sha256", name="uq_sources_sha256"),
    )
    op.create_table(
        "order_types",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("k", sa.Integer(), nullable=False),
        sa.Column("canonical_lambda", sa.String(110), nullable=False),
        sa.Column("unique_min", sa.Boolean(), nullable=False),
        sa.Column("minimal_orderings", sa.Integer(), nullable=False),
        sa.Column("hull_size", sa.Integer(), nullable=False),
        sa.Column("mirror_lambda", sa.String(110), nullable=False),
        sa.Column("chiral", sa.Boolean(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_order_types"),
        sa.UniqueConstraint("k", "canonical_lambda", name="uq_order_types_k_canonical_lambda"),
    )
    op.create_table(
        "realizations",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("order_type_id", sa.Integer(), nullable=False),
        sa.Column("source_id", sa.Integer(), nullable=False),
        sa.Column("record_index", sa.Integer(), nullable=False),
        sa.Column("mirrored", sa.Boolean(), nullable=False),
        sa.Column("coordinates", sa.LargeBinary(), nullable=False),
        sa.Column("mp", sa.Float(), nullable=False),
        sa.Column("canonical_labeling", sa.String(10), nullable=False),
        sa.ForeignKeyConstraint(
            ["order_type_id"],
            ["order_types.id"],
            name="fk_realizations_order_type_id_order_types",
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["source_id"], ["sources.id"], name="fk_realizations_source_id_sources", ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name="pk_realizations"),
        sa.UniqueConstraint(
            "source_id", "record_index", "mirrored", name="uq_realizations_source_id_record_index_mirrored"
        ),
    )
    op.create_index("ix_realizations_order_type_id_mp", "realizations", ["order_type_id", "mp"])


def downgrade() -> None:
    op.drop_index("ix_realizations_order_type_id_mp", table_name="realizations")
    op.drop_table("realizations")
    op.drop_table("order_types")
    op.drop_table("sources")
