"""Every code block of the README and the guides runs: ``python`` blocks and ``sh`` blocks.

Each document runs top to bottom in its own empty folder that holds ``ottag.sqlite``, the bundled
data imported as ``ottag-db import`` imports it (the default database of every command there):
``sh`` blocks as bash scripts (``set -euo pipefail``; ``ottag-db`` and ``python`` are this
interpreter's), ``python`` blocks in one namespace per document, so later blocks see the files
and names of earlier ones. A block right after the line ``<!-- docs-test: skip -->`` is not run
(the set-up commands, which build a virtual environment; minutes-long runs), and neither is a
block of another language (text diagrams, JSON shapes). The README's first two blocks are the
set-up commands, and ``.ci/run`` runs the second one's install and test command.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SKIP = "<!-- docs-test: skip -->"
FENCE = re.compile(r"^(?P<skip><!-- docs-test: skip -->\n)?```(?P<lang>[\w-]*)[^\n]*\n(?P<code>.*?)^```$", re.M | re.S)


def code_blocks(text: str) -> list[tuple[str, str, bool]]:
    """(language, code, skipped) of every fenced block of a Markdown text, in order."""
    return [(m["lang"], m["code"], m["skip"] is not None) for m in FENCE.finditer(text)]


@pytest.fixture(scope="module")
def database(bundled_db_path: Path) -> Path:
    """The bundled data as ``ottag-db import`` leaves it (k = 3 … 8, mirrors included)."""
    return bundled_db_path


def test_the_readme_opens_with_the_two_set_up_commands() -> None:
    blocks = code_blocks((ROOT / "README.md").read_text(encoding="utf-8"))
    (lang1, first, skip1), (lang2, second, skip2) = blocks[:2]
    assert (lang1, lang2, skip1, skip2) == ("sh", "sh", True, True)
    assert first.strip() == (
        "python3 -m venv .venv && . .venv/bin/activate && pip install . && ottag-db import && ottag-db stats "
        "&& ottag-db export --k 8 --min-mp 10 --tag-size 40mm tags.pdf"
    )
    assert second.strip() == (
        "python3 -m venv .venv && . .venv/bin/activate && pip install '.[test]' && python -m pytest -q"
    )
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "pip install --quiet '.[test]'" in ci and "python -m pytest -q" in ci


def test_the_readme_is_short() -> None:
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= 250


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: p.name)
def test_code_blocks_run(document: Path, database: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocks = [(lang, code) for lang, code, skipped in code_blocks(document.read_text(encoding="utf-8")) if not skipped]
    runnable = [(lang, code) for lang, code in blocks if lang in ("python", "sh")]
    if not runnable:
        pytest.skip(f"{document.name} has no runnable code block")
    shutil.copyfile(database, tmp_path / "ottag.sqlite")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("OTTAG_DB", raising=False)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.pop("OTTAG_DB", None)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for i, (lang, code) in enumerate(runnable):
        where = f"{document.name}, block {i + 1}:\n{code}"
        if lang == "sh":
            done = subprocess.run(
                ["bash", "-c", "set -euo pipefail\n" + code], cwd=tmp_path, env=env, capture_output=True, text=True
            )
            assert done.returncode == 0, f"{where}\nstdout:\n{done.stdout}\nstderr:\n{done.stderr}"
        else:
            exec(compile(code, f"<{document.name} block {i + 1}>", "exec"), namespace)
