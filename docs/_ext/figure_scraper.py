"""Gallery scraper for stageid's own figures.

stageid builds its figures with ``matplotlib.figure.Figure`` (no pyplot, so they work under any
backend and in threads); sphinx-gallery's matplotlib scraper only sees pyplot's figures. This
one also saves every ``Figure`` that the example's variables hold and that was not shown yet.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
from matplotlib.figure import Figure
from sphinx_gallery.scrapers import figure_rst, matplotlib_scraper

SHOWN: dict[str, set[int]] = {}


def stageid_figures(block, block_vars, gallery_conf, **kwargs):
    """The pyplot figures, then the example's other ``Figure`` objects, as gallery images."""
    shown = SHOWN.setdefault(block_vars["src_file"], set())
    shown.update(id(plt.figure(number)) for number in plt.get_fignums())  # the pyplot scraper's
    rst = matplotlib_scraper(block, block_vars, gallery_conf, **kwargs)
    paths = []
    for value in list(block_vars["example_globals"].values()):
        if isinstance(value, Figure) and id(value) not in shown:
            shown.add(id(value))
            path = next(block_vars["image_path_iterator"])
            value.savefig(path, dpi=100)
            paths.append(path)
    return rst + figure_rst(paths, gallery_conf["src_dir"]) if paths else rst


def _get_sg_image_scraper():
    """How sphinx-gallery finds this scraper by module name (keeps the configuration picklable)."""
    return stageid_figures
