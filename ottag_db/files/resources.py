"""Locate files shipped with the package (migrations, bundled data) in a wheel or a checkout."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["data_dir", "migrations_dir"]

_CHECKOUT_ROOT = Path(__file__).resolve().parents[2]


def _package_dir(package: str, checkout_name: str) -> Path:
    # Installed (wheel or editable): the folder ships as the sub-package `package`.
    # Plain checkout on sys.path: the folder sits at the top of the repository.
    try:
        path = Path(str(resources.files(package)))
    except ModuleNotFoundError:
        path = _CHECKOUT_ROOT / checkout_name
    return path


def migrations_dir() -> Path:
    """Folder with Alembic's env.py and versions/.

    Returns
    -------
    Path
        The installed sub-package ``ottag_db.migrations``, or ``migrations/`` of a checkout.
    """
    return _package_dir("ottag_db.migrations", "migrations")


def data_dir() -> Path:
    """Folder with the bundled point-set files and manifest.json.

    Returns
    -------
    Path
        The installed sub-package ``ottag_db.data``, or ``data/`` of a checkout.
    """
    return _package_dir("ottag_db.data", "data")
