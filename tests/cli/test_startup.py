"""Start-up cost: a command imports only the heavy libraries it uses.

Each check runs the command line in a fresh interpreter and reads ``sys.modules`` afterwards,
so an import added anywhere on the path of ``--version`` shows up here.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

#: Heavy third-party packages: a command that does not need one must not import it.
HEAVY = ("numpy", "cv2", "scipy", "reportlab", "sqlalchemy", "alembic", "numba")

_PROBE = """
import json, sys
from ottag_db.cli import main
watched = set(json.loads(sys.argv[2]))
sys.argv = ["ottag-db", *json.loads(sys.argv[1])]
try:
    main()
except SystemExit as exc:
    code = exc.code
else:
    code = 0
heavy = sorted({m.split(".")[0] for m in sys.modules} & watched)
print(json.dumps({"code": code, "heavy": heavy}), file=sys.stderr)
"""


def _loaded(args: list[str]) -> set[str]:
    """Heavy packages in ``sys.modules`` after ``ottag-db ARGS`` ran (and succeeded)."""
    proc = subprocess.run(
        [sys.executable, "-c", _PROBE, json.dumps(args), json.dumps(HEAVY)],
        capture_output=True,
        text=True,
        check=True,
    )
    report = json.loads(proc.stderr.strip().splitlines()[-1])
    assert report["code"] in (0, None), proc.stderr
    return set(report["heavy"])


@pytest.mark.parametrize(
    "args", [["--version"], ["--help"], ["export", "--help"], ["decode", "--help"], ["dictionary", "--help"]]
)
def test_version_and_help_import_nothing_heavy(args: list[str]) -> None:
    assert _loaded(args) == set()


def test_importing_the_package_imports_nothing_heavy() -> None:
    code = "import sys, ottag_db; print(sorted({m.split('.')[0] for m in sys.modules} & set(sys.argv[1:])))"
    out = subprocess.run([sys.executable, "-c", code, *HEAVY], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.fixture(scope="module")
def db_file(bundled_db_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("startup") / "bundled.sqlite"
    shutil.copyfile(bundled_db_path, path)
    return path


@pytest.mark.parametrize(
    "args",
    [
        ["stats"],
        ["list", "--k", "5"],
        ["show", "1"],
        ["id", "0,0 69,255 149,116 138,72 255,69"],
        ["db", "current"],
    ],
)
def test_database_commands_skip_opencv_scipy_reportlab(args: list[str], db_file: Path) -> None:
    loaded = _loaded([*args, "--db", str(db_file), "-q"] if args[0] != "db" else [*args, "--db", str(db_file)])
    assert {"sqlalchemy", "alembic"} <= loaded
    assert not loaded & {"cv2", "scipy", "reportlab"}
