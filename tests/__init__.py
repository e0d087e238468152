"""ottag-db test suite (mirrors the package modules)."""
