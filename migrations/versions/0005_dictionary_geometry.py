"""Dictionary members name the realization they are printed from and verified against.

``dictionary import`` stores the geometry of a dictionary file (points, triangles) as
realizations and layouts of its own source, and ``dictionary create`` pins each member's best
realization at creation; ``dictionary_tags.realization_id`` points at it. Members of older
dictionaries keep NULL (best realization, verified against all realizations, as before).

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-01
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    columns = {c["name"] for c in sa.inspect(op.get_bind()).get_columns("dictionary_tags")}
    if "realization_id" in columns:  # a file whose version row was set back by hand: nothing to add
        return
    with op.batch_alter_table("dictionary_tags") as batch:
        batch.add_column(sa.Column("realization_id", sa.Integer(), nullable=True))
        batch.create_foreign_key(
            "fk_dictionary_tags_realization_id_realizations",
            "realizations",
            ["realization_id"],
            ["id"],
            ondelete="SET NULL",
        )


def downgrade() -> None:
    with op.batch_alter_table("dictionary_tags") as batch:
        batch.drop_constraint("fk_dictionary_tags_realization_id_realizations", type_="foreignkey")
        batch.drop_column("realization_id")
