"""Sphinx configuration of skewpend's documentation.

Build (one command, from the project root)::

    pip install -e ".[docs]" && sphinx-build -W --keep-going -b html docs docs/_build/html

The tutorials (``docs/tutorials/*.md``, MyST-NB text notebooks) are executed at build time
(cached in ``docs/_build/.jupyter_cache``); the gallery's scripts (``docs/gallery/plot_*.py``)
are run by sphinx-gallery; mathematics is rendered to HTML at build time by the KaTeX that the
package bundles (Node.js runs it), so the built site needs no JavaScript for formulas and no
network: it opens from the file system.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(ROOT / "src"))

import skewpend  # noqa: E402

project = "skewpend"
author = "the skewpend developers"
copyright = "2026, the skewpend developers"
release = version = skewpend.__version__

extensions = [
    "myst_nb",  # MyST markdown pages and executed text notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "sphinxcontrib.katex",
    "sphinx_gallery.gen_gallery",
    "sphinx_copybutton",
    "skewpend_docs",  # docs/_ext/skewpend_docs.py: the API reference's completeness check
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb"}  # (the gallery writes .ipynb files: not sources)
exclude_patterns = ["_build", "gallery/README.txt", "sg_execution_times.rst", "auto_gallery/*.ipynb", "**.ipynb_checkpoints", "jupyter_execute"]
root_doc = "index"

# --- MyST and notebooks ----------------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist", "attrs_inline"]
myst_heading_anchors = 3
nb_execution_mode = os.environ.get("SKEWPEND_DOCS_EXECUTE", "cache")  # 'off' for a quick look
nb_execution_timeout = 180  # seconds per notebook
nb_execution_in_temp = True  # each notebook runs in a temporary directory: the files it writes go there
nb_execution_raise_on_error = True  # a failing cell fails the build
nb_execution_show_tb = True
nb_execution_cache_path = str(HERE / "_build" / ".jupyter_cache")
nb_merge_streams = True
nb_ipywidgets_js = {}  # no widget manager from a CDN: the site is offline (the widget tutorial shows a picture)
suppress_warnings = ["myst-nb.lexer"] if nb_execution_mode == "off" else []  # no kernel asked: no lexer

# --- mathematics: KaTeX at build time, from the package's own copy --------------------------
KATEX = ROOT / "src" / "skewpend" / "views" / "assets" / "katex"
katex_prerender = True
katex_js_path = str(KATEX / "katex.min.js")
katex_css_path = "katex/katex.min.css"  # copied with its fonts from the package (html_static_path)
katex_options = "throwOnError: true"

# --- API reference ---------------------------------------------------------------------------
autosummary_generate = True
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autoclass_content = "both"
napoleon_numpy_docstring = True
napoleon_google_docstring = False

# --- gallery ---------------------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": "gallery",
    "gallery_dirs": "auto_gallery",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "matplotlib_animations": False,
    "image_srcset": [],
    "within_subsection_order": "FileNameSortKey",
    "show_memory": False,
    "write_computation_times": False,  # its page loads DataTables from a CDN: the site stays offline
    "image_scrapers": ("skewpend_docs",),  # skewpend's figures (docs/_ext/skewpend_docs.py)
    "reset_modules": (),
}

# --- HTML ------------------------------------------------------------------------------------
html_theme = "furo"
html_title = f"skewpend {release}"
html_static_path = ["_static", str(KATEX.parent)]  # the second gives _static/katex/
html_css_files = ["skewpend.css"]
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": True,
}
html_last_updated_fmt = None
pygments_style = "sphinx"
copybutton_prompt_text = r"\$ "
copybutton_prompt_is_regexp = True

# no request may leave the machine while building or reading the site
intersphinx_mapping: dict = {}
linkcheck_ignore = [r".*"]
