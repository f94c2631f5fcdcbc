"""Self-contained HTML reports: text, tables and figures embedded as base64 PNG."""

from __future__ import annotations

import base64
import html
import io
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..atomic import atomic_write_text, check_parent, staged_folder
from ..display import html_repr, short_repr

__all__ = ["Report", "write_metrics", "write_report_folder"]

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1180px;margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.7em;border-bottom:2px solid #345;padding-bottom:.2em}
h2{font-size:1.3em;margin-top:2em;border-bottom:1px solid #bbb}
h3{font-size:1.05em;margin-top:1.4em}
table{border-collapse:collapse;margin:.8em 0;font-size:.92em}
th,td{border:1px solid #ccc;padding:.3em .6em;text-align:right}
th{background:#eef2f6}
td:first-child,th:first-child{text-align:left}
figure{margin:1.2em 0}
figure img{max-width:100%;height:auto;border:1px solid #ddd}
figcaption{font-size:.9em;color:#444;margin-top:.3em}
.pass{color:#1a7f37;font-weight:600}.fail{color:#b42318;font-weight:600}
nav ul{columns:2}
code{background:#f3f3f3;padding:0 .2em}
"""


@dataclass
class _Block:
    kind: str
    payload: Any


@dataclass
class Report:
    """Collects sections, paragraphs, tables and figures, then writes one ``index.html``.

    Figures are rendered to PNG at once and embedded as base64, so the report is one
    self-contained file (no external images, scripts or fonts).

    Examples
    --------
    >>> from stageid.report import Report
    >>> r = Report("Example")
    >>> r.section("Data")
    >>> r.paragraph("Three chirp experiments at Ts = 2 ms.")
    >>> r.table(["metric", "value"], [["fit z [%]", 98.2]])
    >>> "<table>" in r.to_html()
    True
    """

    title: str
    blocks: list[_Block] = field(default_factory=list)
    n_figures: int = 0
    units: dict[str, str] = field(default_factory=dict)

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    def section(self, title: str, level: int = 2) -> None:
        """Start a section (``level`` 2) or sub-section (3)."""
        self.blocks.append(_Block("h", (level, title)))

    def paragraph(self, text: str) -> None:
        """A paragraph of plain text (escaped)."""
        self.blocks.append(_Block("p", text))

    def bullets(self, items: Sequence[str]) -> None:
        """A list of short plain-text items (escaped), one line each."""
        self.blocks.append(_Block("ul", [str(i) for i in items]))

    def table(self, header: Sequence[str], rows: Sequence[Sequence[Any]], caption: str = "") -> None:
        """A table; floats are printed with 4 significant digits, NaN (an undefined value) as "n/a"."""
        self.blocks.append(_Block("table", (list(header), [list(r) for r in rows], caption)))

    def unit(self, key: str, unit: str) -> None:
        """The unit of metric ``key`` where its name cannot say it (a gain in the records' units);
        written into the ``units`` map of ``metrics.json`` (:mod:`stageid.report.units`)."""
        self.units[key] = unit

    def figure(self, fig: Any, caption: str, dpi: int = 110) -> None:
        """Embed a matplotlib figure (rendered to PNG now) with a caption."""
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        self.n_figures += 1
        self.blocks.append(
            _Block("figure", (base64.b64encode(buf.getvalue()).decode("ascii"), caption, self.n_figures))
        )

    def to_html(self) -> str:
        """The whole report as one HTML document."""
        out = [
            f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{html.escape(self.title)}</title>",
            f"<meta name='viewport' content='width=device-width, initial-scale=1'><style>{_CSS}</style></head><body>",
            f"<h1>{html.escape(self.title)}</h1>",
        ]
        toc = [b.payload[1] for b in self.blocks if b.kind == "h" and b.payload[0] == 2]
        if len(toc) > 1:
            out.append(
                "<nav><ul>"
                + "".join(f"<li><a href='#s{k}'>{html.escape(t)}</a></li>" for k, t in enumerate(toc))
                + "</ul></nav>"
            )
        k = 0
        for b in self.blocks:
            if b.kind == "h":
                level, title = b.payload
                anchor = f" id='s{k}'" if level == 2 else ""
                k += level == 2
                out.append(f"<h{level}{anchor}>{html.escape(title)}</h{level}>")
            elif b.kind == "p":
                out.append(f"<p>{html.escape(b.payload)}</p>")
            elif b.kind == "ul":
                out.append("<ul>" + "".join(f"<li>{html.escape(i)}</li>" for i in b.payload) + "</ul>")
            elif b.kind == "table":
                header, rows, caption = b.payload
                cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
                head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
                body = "".join("<tr>" + "".join(f"<td>{_cell(c)}</td>" for c in r) + "</tr>" for r in rows)
                out.append(f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")
            elif b.kind == "figure":
                data, caption, number = b.payload
                alt = html.escape(caption, quote=True)
                out.append(
                    f"<figure><img src='data:image/png;base64,{data}' alt='{alt}'>"
                    f"<figcaption>Figure {number}. {html.escape(caption)}</figcaption></figure>"
                )
        out.append("</body></html>\n")
        return "\n".join(out)

    def write(self, folder: str | os.PathLike[str], name: str = "index.html") -> Path:
        """Write the report into ``folder`` (created if needed; its parent must exist) atomically; returns the file path."""
        check_parent(folder).mkdir(exist_ok=True)
        return atomic_write_text(Path(folder) / name, self.to_html())


def _cell(value: Any) -> str:
    if isinstance(value, bool):
        return "<span class='pass'>yes</span>" if value else "<span class='fail'>no</span>"
    if isinstance(value, float):
        return "n/a" if math.isnan(value) else html.escape(f"{value:.4g}")
    return html.escape(str(value))


def _json_safe(value: Any) -> Any:
    """Non-finite floats (an undefined metric, e.g. the fit of a constant channel) -> None."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):  # numpy float64 is a float too
        return None
    return value


def metrics_json(metrics: dict[str, Any]) -> str:
    """The text of ``metrics.json``: sorted keys, non-finite numbers written as ``null``."""
    return json.dumps(_json_safe(metrics), indent=2, sort_keys=True, allow_nan=False) + "\n"


def with_units(metrics: dict[str, Any], known: dict[str, str] | None = None) -> dict[str, Any]:
    """``metrics`` and a ``units`` map: the unit of each of its numbers (:func:`~stageid.report.units.metric_units`)."""
    from .units import metric_units

    return {**metrics, "units": metric_units(metrics, known)}


def write_metrics(
    folder: str | os.PathLike[str], metrics: dict[str, Any], name: str = "metrics.json", units: dict | None = None
) -> Path:
    """Write a metrics dictionary as JSON (sorted keys) atomically, with its ``units`` map.

    Undefined values (NaN, +-inf, e.g. the fit % of a constant channel) are written as
    ``null``: strict JSON has no NaN.  ``units`` gives the units the keys' names cannot say.
    """
    check_parent(folder).mkdir(exist_ok=True)
    return atomic_write_text(Path(folder) / name, metrics_json(with_units(metrics, units)))


def write_report_folder(folder: str | os.PathLike[str], report: Report, metrics: dict[str, Any] | None = None) -> Path:
    """Write ``index.html`` (and ``metrics.json``) into ``folder`` all at once; returns the HTML path.

    Both files are rendered in memory, written into a temporary folder next to ``folder``
    and then moved into place (:func:`stageid.atomic.staged_folder`: the folder is renamed
    when it does not exist yet), so a failure leaves neither a new folder nor half a report
    behind.

    Parameters
    ----------
    folder : str or path-like
        The report folder; its parent must exist.
    report : Report
    metrics : dict, optional
        Written as ``metrics.json`` (see :func:`write_metrics`), with the units of
        :meth:`Report.unit`.

    Returns
    -------
    pathlib.Path
        ``folder / "index.html"``.

    Raises
    ------
    DataError
        When the parent folder does not exist or ``folder`` is an existing file.

    Examples
    --------
    >>> import os, tempfile
    >>> from stageid.report import Report, write_report_folder
    >>> out = os.path.join(tempfile.mkdtemp(), "rep")
    >>> write_report_folder(out, Report("Empty"), {"fit": float("nan")}).name
    'index.html'
    >>> open(os.path.join(out, "metrics.json")).read()
    '{\\n  "fit": null,\\n  "units": {}\\n}\\n'
    """
    files = {"index.html": report.to_html()}
    if metrics is not None:
        files["metrics.json"] = metrics_json(with_units(metrics, report.units))
    with staged_folder(folder) as tmp:
        for name, text in files.items():
            atomic_write_text(tmp / name, text)
    return Path(folder) / "index.html"
