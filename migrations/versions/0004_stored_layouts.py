"""Store the layout and placement of every drawable realization that has none.

Before this revision layouts were computed on the first export (a read that wrote); now
``import`` stores them, and this data migration fills them in for older databases so that
every later read finds them. No schema change. (The database file is backed up before any
migration, see ``ottag_db.store.db.open_database``.)

Revision ID: 0004
Revises: 0003
Create Date: 2026-12-01
"""

from __future__ import annotations

from alembic import op

from ottag_db.store.layouts import add_missing_layouts

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    add_missing_layouts(op.get_bind())


def downgrade() -> None:
    # Layouts are derived data that revision 0003 may hold too; keeping them is harmless.
    pass
