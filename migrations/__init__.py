"""Alembic migrations of the ottag database schema."""
