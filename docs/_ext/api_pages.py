"""Write one API page per package from its ``__all__`` before autosummary reads them.

The pages are build output (ignored by git): a name added to or removed from a package's
``__all__`` appears on or leaves the site at the next build, with no page to edit.
"""

from __future__ import annotations

from pathlib import Path

PAGE = """{title}
{underline}

.. automodule:: {package}
   :no-members:
   :no-index:

.. currentmodule:: {package}

.. autosummary::
   :toctree: generated/
   :nosignatures:

{names}
"""

INDEX = """API reference
=============

Every public name of stageid: what ``stageid.__all__`` and each sub-package's ``__all__``
export.  Arrays are ``(n_samples, n_channels)``, time first; shapes are in each docstring.

.. list-table::
   :header-rows: 1
   :widths: 30 70

   * - package
     - what it holds
{rows}

.. toctree::
   :hidden:

{entries}
"""


def write_pages(app, config) -> None:
    """Write ``api/<package>.rst`` for every package of ``API_PACKAGES`` and ``api/index.rst``."""
    folder = Path(app.srcdir) / "api"
    folder.mkdir(exist_ok=True)
    rows, entries = [], []
    for package, summary in config.api_packages:
        names = config.api_public_names(package)
        title = f"``{package}``"
        text = PAGE.format(
            title=title,
            underline="=" * len(title),
            package=package,
            names="\n".join(f"   {name}" for name in names),
        )
        update(folder / f"{package}.rst", text)
        rows.append(f"   * - :doc:`{package} <{package}>`\n     - {summary}")
        entries.append(f"   {package}")
    update(folder / "index.rst", INDEX.format(rows="\n".join(rows), entries="\n".join(entries)))


def update(path: Path, text: str) -> None:
    """Write only when the text changed, so an incremental build does not redo every page."""
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def setup(app):
    app.add_config_value("api_packages", [], "env")
    app.add_config_value("api_public_names", None, "")
    app.connect("config-inited", write_pages)  # before the source files are listed
    return {"parallel_read_safe": True, "version": "1"}
