"""Triangle layouts and tag placements of realizations.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "layouts",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("realization_id", sa.Integer(), nullable=False),
        sa.Column("triangles", sa.String(200), nullable=False),
        sa.Column("triangle_count", sa.Integer(), nullable=False),
        sa.Column("min_angle_deg", sa.Float(), nullable=False),
        sa.Column("min_side", sa.Float(), nullable=False),
        sa.Column("min_gap", sa.Float(), nullable=True),
        sa.Column("min_shared_gap_deg", sa.Float(), nullable=True),
        sa.Column("score", sa.Float(), nullable=False),
        sa.Column("placement", sa.String(400), nullable=False),
        sa.Column("printed_mp_unit", sa.Float(), nullable=False),
        sa.ForeignKeyConstraint(
            ["realization_id"], ["realizations.id"], name="fk_layouts_realization_id_realizations", ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name="pk_layouts"),
        sa.UniqueConstraint("realization_id", name="uq_layouts_realization_id"),
    )


def downgrade() -> None:
    op.drop_table("layouts")
