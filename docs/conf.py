# Sphinx configuration of the hindsight manual (Debian python3-sphinx and python3-myst-parser). Built by
# the CMake target `docs` and checked with warnings as errors by the ctest entry docs.sphinx.
import os

project = "hindsight"
author = "the hindsight authors"
copyright = "the hindsight authors, BSD 3-Clause license"
version = release = os.environ.get("HINDSIGHT_VERSION", "")

extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
root_doc = "index"
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3
exclude_patterns = ["_build", "images"]
html_theme = "alabaster"
html_static_path = []
# The API reference is Doxygen's HTML, generated beside this manual (CMake target docs: api/).
html_extra_path = []


# Four guides are written beside this manual's other pages and may be absent from a checkout that
# predates them (storage strategies, crashes and resume, PETSc, performance): the index lists them, and
# an absent one is dropped from its toctree here rather than left as a dangling entry. Any other missing
# page is still an error.
_optional_guides = ["guides/storage_strategies", "guides/crashes_and_resume", "guides/petsc", "guides/performance"]


def _drop_absent_optional_guides(app, docname, source):
    if docname != "index":
        return
    here = os.path.dirname(os.path.abspath(__file__))
    for guide in _optional_guides:
        if not os.path.exists(os.path.join(here, guide + ".md")):
            source[0] = source[0].replace(guide + "\n", "")


def setup(app):
    app.connect("source-read", _drop_absent_optional_guides)
