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


