"""Universal numbers, the flip graph and named tag dictionaries.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("order_types") as batch:
        batch.add_column(sa.Column("number", sa.Integer(), nullable=True))
        batch.create_unique_constraint("uq_order_types_k_number", ["k", "number"])
    op.create_table(
        "flip_edges",
        sa.Column("source_id", sa.Integer(), nullable=False),
        sa.Column("target_id", sa.Integer(), nullable=False),
        sa.Column("triple", sa.String(8), nullable=False),
        sa.ForeignKeyConstraint(
            ["source_id"], ["order_types.id"], name="fk_flip_edges_source_id_order_types", ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["target_id"], ["order_types.id"], name="fk_flip_edges_target_id_order_types", ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("source_id", "target_id", "triple", name="pk_flip_edges"),
    )
    op.create_index("ix_flip_edges_target_id", "flip_edges", ["target_id"])
    op.create_table(
        "flip_graph_status",
        sa.Column("k", sa.Integer(), nullable=False),
        sa.Column("order_types", sa.Integer(), nullable=False),
        sa.Column("edges", sa.Integer(), nullable=False),
        sa.Column("computed_at", sa.DateTime(), nullable=False),
        sa.PrimaryKeyConstraint("k", name="pk_flip_graph_status"),
    )
    op.create_table(
        "dictionaries",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(100), nullable=False),
        sa.Column("min_flip_distance", sa.Integer(), nullable=False),
        sa.Column("parameters", sa.Text(), nullable=False),
        sa.Column("created_at", sa.DateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_dictionaries"),
        sa.UniqueConstraint("name", name="uq_dictionaries_name"),
    )
    op.create_table(
        "dictionary_tags",
        sa.Column("dictionary_id", sa.Integer(), nullable=False),
        sa.Column("number", sa.Integer(), nullable=False),
        sa.Column("order_type_id", sa.Integer(), nullable=False),
        sa.Column("polarity", sa.String(10), nullable=False),
        sa.CheckConstraint("polarity IN ('normal', 'inverted')", name=op.f("ck_dictionary_tags_polarity")),
        sa.ForeignKeyConstraint(
            ["dictionary_id"],
            ["dictionaries.id"],
            name="fk_dictionary_tags_dictionary_id_dictionaries",
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["order_type_id"],
            ["order_types.id"],
            name="fk_dictionary_tags_order_type_id_order_types",
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("dictionary_id", "number", name="pk_dictionary_tags"),
        sa.UniqueConstraint(
            "dictionary_id", "order_type_id", "polarity", name="uq_dictionary_tags_dictionary_id_order_type_id_polarity"
        ),
    )


def downgrade() -> None:
    op.drop_table("dictionary_tags")
    op.drop_table("dictionaries")
    op.drop_table("flip_graph_status")
    op.drop_index("ix_flip_edges_target_id", table_name="flip_edges")
    op.drop_table("flip_edges")
    with op.batch_alter_table("order_types") as batch:
        batch.drop_constraint("uq_order_types_k_number", type_="unique")
        batch.drop_column("number")
