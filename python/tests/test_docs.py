"""The Python code blocks of the README and of every page under docs/ run as written: each page's blocks
in order, as one script, in a scratch directory (so a page may build on its earlier blocks). A block
preceded by <!-- not-run: REASON --> is skipped: at present the checkpoint_schedules side of
docs/guides/switching_from_checkpoint_schedules.md, which needs a package CI does not install."""
import os
import re
import runpy
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
FENCE = re.compile(r"(<!--\s*not-run:[^>]*-->\s*\n)?^(`{3,})python[^\n]*\n(.*?)^\2[ \t]*$", re.S | re.M)


def pages():
    found = [os.path.join(ROOT, "README.md")]
    for directory, _, files in os.walk(os.path.join(ROOT, "docs")):
        found += [os.path.join(directory, name) for name in sorted(files) if name.endswith(".md")]
    return sorted(page for page in found if "```python" in open(page, encoding="utf-8").read())


@pytest.mark.parametrize("page", pages(), ids=lambda page: os.path.relpath(page, ROOT))
def test_python_blocks_run_as_written(page, tmp_path, monkeypatch):
    with open(page, encoding="utf-8") as f:
        blocks = [m.group(3) for m in FENCE.finditer(f.read()) if not m.group(1)]
    assert blocks, page
    monkeypatch.chdir(tmp_path)
    script = tmp_path / "page.py"
    script.write_text("\n".join(blocks))
    monkeypatch.setattr(sys, "argv", [str(script)])
    runpy.run_path(str(script), run_name="__main__")


def test_every_page_with_python_is_found():
    names = {os.path.relpath(page, ROOT) for page in pages()}
    assert "README.md" in names
    assert os.path.join("docs", "tutorials", "own_ode_python.md") in names
