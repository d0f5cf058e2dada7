"""Sphinx configuration for the quatarray documentation.

Build (from the repository root)::

    python -m sphinx -W -b html docs docs/_build/html

The API reference is generated at build time from the public names
(``quatarray.__all__`` and the public submodules), so it follows the API:
``_apigen.py`` writes ``api/index.rst`` (grouped autosummary tables) and
autosummary writes one page per class and function under ``api/generated/``.
Both are build products, ignored by git.
"""

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))   # the checkout's quatarray, installed or not
sys.path.insert(0, HERE)                    # _apigen

import quatarray  # noqa: E402
import _apigen  # noqa: E402

project = "quatarray"
author = "the quatarray developers"
copyright = "the quatarray developers, BSD-3-Clause"
version = release = quatarray.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.doctest",
    "_mathml",
    "numpydoc",
    "matplotlib.sphinxext.plot_directive",
]

exclude_patterns = ["_build"]
templates_path = ["_templates"]
html_static_path = ["_static"]
root_doc = "index"

# -- API reference ---------------------------------------------------------
# The group pages are named, not found: a page new since the last build gets its stubs too.
autosummary_generate = _apigen.write_api_pages(HERE)
autosummary_imported_members = True
autosummary_ignore_module_all = False
# The class template documents only the members quatarray defines, not the
# ~150 inherited from numpy.ndarray (see _templates/autosummary/class.rst).
autosummary_context = {"own_members": _apigen.own_members()}
autodoc_typehints = "none"
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks = set()
# Single backticks in docstrings (`Track`, `keys`) link when they name an
# object and stay plain otherwise.
default_role = "py:obj"

# -- accuracy: measured at build time, so the figures follow the formulas --------
import _accuracy  # noqa: E402

_ACCURACY_SAMPLES = 300
_apigen._write(os.path.join(HERE, "guide", "accuracy_table.inc"),
               _accuracy.rst_table(_accuracy.measure(_ACCURACY_SAMPLES), _ACCURACY_SAMPLES))

# -- doctest: only the guide's explicit ``.. doctest::`` blocks -------------
# (docstring examples are run by pytest --doctest-modules)
doctest_test_doctest_blocks = ""
doctest_global_setup = "import numpy as np"

# -- plots: built from the code in the pages ---------------------------------
plot_working_directory = HERE      # data files are named relative to docs/
plot_include_source = True
plot_html_show_source_link = False
plot_html_show_formats = False
plot_formats = [("png", 96)]
plot_rcparams = {"figure.figsize": (7.0, 3.4), "figure.dpi": 96, "savefig.bbox": "tight",
                 "axes.grid": True, "grid.alpha": 0.3}
plot_pre_code = """
import numpy as np
import matplotlib.pyplot as plt
"""

# -- HTML --------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_math_renderer = "mathml"      # formulas as MathML: no JavaScript, nothing fetched
html_title = f"quatarray {release}"
html_theme_options = {
    "navbar_align": "left",
    "show_toc_level": 2,
    "navigation_with_keys": False,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_sidebars = {"index": []}
html_favicon = "_static/favicon.svg"
html_css_files = ["quatarray.css"]
# The theme's script logs an error for an unset mode on a first visit; say it.
html_context = {"default_mode": "auto"}
html_show_sourcelink = False


# -- docstrings: plain-text notation that reStructuredText would misread ----------
# The docstrings are written for help() as much as for Sphinx: ``|q|`` is a norm, not
# a substitution, and ``(K, *batch)`` is a shape, not the start of emphasis. Escape
# those (outside literals, code and doctest blocks) instead of warning.
import re  # noqa: E402

_INLINE_CODE = re.compile(r"(``.+?``|`[^`]+`)")
_STAR_NAME = re.compile(r"(?<=[(\[, ])\*(?=[,)\]]|[A-Za-z_][\w.]*[,)\]])")   # (K, *batch), f(a, *, b)


def _escape_prose(text):
    parts = _INLINE_CODE.split(text)
    for i in range(0, len(parts), 2):         # even parts lie outside backticks
        parts[i] = _STAR_NAME.sub(r"\\*", parts[i].replace("|", r"\|"))
    return "".join(parts)


def _escape_docstring(app, what, name, obj, options, lines):
    literal_indent = None     # indentation of the line that opened a literal block
    doctest = False
    for i, line in enumerate(lines):
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if not stripped:
            doctest = False
            continue
        if literal_indent is not None:
            if indent > literal_indent:
                continue
            literal_indent = None
        if stripped.startswith(">>>") or doctest:
            doctest = True
            continue
        if stripped.startswith((".. ", "|")) or set(stripped) <= set("+-=|: "):
            pass                                 # directives, line blocks, table rules
        else:
            lines[i] = _escape_prose(line)
        if stripped.endswith("::"):
            literal_indent = indent


def setup(app):
    app.connect("autodoc-process-docstring", _escape_docstring, priority=400)
