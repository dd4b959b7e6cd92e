"""
Sphinx configuration of the documentation site: the Markdown pages of ``docs/`` (MyST) and an API reference from the
docstrings (autodoc). Build it as CI does, warnings as errors (``make docs``, tests/test_docs_build.py)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

autodoc imports the installed ``sb3_maddpg`` and ``sb3_maddpg_envs`` (``pip install -e ".[docs]"`` installs the
checkout and the documentation's packages).
"""

import re
from pathlib import Path

from docutils import nodes
from sphinx import addnodes
from sphinx.application import Sphinx
from sphinx.transforms.post_transforms import SphinxPostTransform

import sb3_maddpg

project = "sb3_maddpg"
author = "the sb3_maddpg authors"
copyright = author
version = release = sb3_maddpg.__version__

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.viewcode"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
# the notebook is linked from the pages (a download), not a page of its own
exclude_patterns = ["_build", "notebooks"]

# The pages link to headings as GitHub names them (tests/test_docs_links.py checks those links), down to ###: MyST
# gives the headings of these levels anchors, its slugs being GitHub's
myst_heading_anchors = 4

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented_params"
# defaults as the source writes them (buffer_size=1_000_000, learning_rate=1e-3)
autodoc_preserve_defaults = True
add_module_names = False

html_theme = "sphinx_rtd_theme"
html_title = f"sb3_maddpg {release}"
html_theme_options = {"navigation_depth": 3}

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent

# The docstrings write shapes as Python unpacks them, (B, N, *obs_shape); reST would read that star as the start of
# an emphasis. Escape a star that unpacks a name inside a tuple for reST only: the docstrings stay as help() shows them.
UNPACKED_SHAPE = re.compile(r"(?<=[(, ])\*(?=\w+[),])")


def escape_unpacked_shapes(app: Sphinx, what: str, name: str, obj: object, options: dict, lines: list[str]) -> None:
    lines[:] = [UNPACKED_SHAPE.sub(r"\\*", line) for line in lines]


class RepositoryFolderLinks(SphinxPostTransform):
    """
    A page may link to a folder of the repository outside ``docs/`` (the raw run logs under ``experiments/results/``):
    GitHub shows the folder's files, but a folder is no page or file of the site, and MyST would report the link as a
    missing reference. Such a link keeps its text (the folder's path) without a target on the site. Links to files
    outside ``docs/`` are MyST's downloads (the file is copied into the site); any other unresolved link still fails
    the build.
    """

    default_priority = 8  # before MyST's reference resolver (9)

    def run(self, **kwargs: object) -> None:
        for node in list(self.document.findall(addnodes.pending_xref)):
            if node.get("reftype") != "myst" or node.get("refdomain") is not None:
                continue
            page = Path(self.env.doc2path(node["refdoc"])).parent
            target = (page / node["reftarget"].partition("#")[0]).resolve()
            if target.is_dir() and target.is_relative_to(ROOT) and not target.is_relative_to(DOCS):
                node.replace_self(nodes.inline("", "", *node[0].children, classes=["repository-folder"]))


def setup(app: Sphinx) -> None:
    app.connect("autodoc-process-docstring", escape_unpacked_shapes)
    app.add_post_transform(RepositoryFolderLinks)
