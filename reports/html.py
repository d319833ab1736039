"""A minimal, dependency-free HTML page builder and atomic report-folder writer."""

from __future__ import annotations

import html
import io
import os
import shutil
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

__all__ = ["HtmlPage", "write_report_dir", "fmt"]

_CSS = (
    "\n"
    "body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1150px;"
    "margin:2em auto;padding:0 1em;color:#222}\n"
    "h1{font-size:1.6em}h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;"
    "margin-top:1.8em}\n"
    "table{border-collapse:collapse;margin:.8em 0;font-size:.9em}td,th{border:1px solid #ccc;"
    "padding:.25em .55em;text-align:left;vertical-align:top}\n"
    "th{background:#f3f3f3}.holds{background:#d9f2d9;font-weight:600}"
    ".fails{background:#f8d7d7;font-weight:600}\n"
    ".nt{background:#eee;font-weight:600}figure{margin:1em 0}figcaption{font-size:.9em;"
    "color:#444}img{max-width:100%}\n"
    "code{background:#f5f5f5;padding:0 .2em}.note{color:#555;font-size:.9em}\n"
)


def fmt(x, digits: int = 4) -> str:
    """Format a number compactly for tables.

    Parameters
    ----------
    x : object
        A bool (``"yes"``/``"no"``), an int (exact), anything ``float`` accepts
        (``digits`` significant digits; ``"nan"``, ``"inf"``, ``"-inf"``), or any
        other object (its ``str``).
    digits : int
        Significant digits of a non-integer number.

    Returns
    -------
    str
    """
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int,)):
        return str(x)
    try:
        xf = float(x)
    except (TypeError, ValueError):
        return str(x)
    if xf != xf:
        return "nan"
    if xf in (float("inf"), float("-inf")):
        return "inf" if xf > 0 else "-inf"
    return f"{xf:.{digits}g}"


class HtmlPage:
    """Accumulates sections of one HTML page; figures are saved as PNG files beside it.

    Parameters
    ----------
    title : str
        Page title (``<title>`` and the ``<h1>`` heading).

    Attributes
    ----------
    files : dict of str to bytes
        Files written beside ``index.html``: the figures' PNGs and attachments.
    """

    def __init__(self, title: str):
        self.title = title
        self._parts: list[str] = []
        self.files: dict[str, bytes] = {}

    def h2(self, text: str) -> None:
        """Append a section heading (``text`` is escaped)."""
        self._parts.append(f"<h2>{html.escape(text)}</h2>")

    def p(self, text: str, *, raw: bool = False, cls: str | None = None) -> None:
        """Append a paragraph: ``text`` escaped unless ``raw``, with CSS class ``cls`` if given."""
        body = text if raw else html.escape(text)
        c = f' class="{cls}"' if cls else ""
        self._parts.append(f"<p{c}>{body}</p>")

    def table(
        self,
        header: list[str],
        rows: list[list],
        *,
        row_classes: list[str | None] | None = None,
        raw_cols=(),
    ) -> None:
        """Append a table.

        Cells that are not strings are formatted with :func:`fmt`; cells are escaped
        except in the columns ``raw_cols`` (indices). ``row_classes[i]``, if given and
        not ``None``, is the CSS class (``"holds"``, ``"fails"``, ``"nt"``) of row
        ``i``'s second cell.
        """
        out = ["<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>"]
        for i, row in enumerate(rows):
            cells = []
            for j, v in enumerate(row):
                text = v if j in raw_cols else html.escape(v if isinstance(v, str) else fmt(v))
                cls = row_classes[i] if (row_classes and j == 1 and row_classes[i]) else None
                cells.append(f'<td class="{cls}">{text}</td>' if cls else f"<td>{text}</td>")
            out.append("<tr>" + "".join(cells) + "</tr>")
        out.append("</table>")
        self._parts.append("".join(out))

    def figure(self, fig, name: str, caption: str) -> None:
        """Append a matplotlib figure saved as ``<name>.png`` (110 dpi), then close it."""
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        fname = f"{name}.png"
        self.files[fname] = buf.getvalue()
        self._parts.append(
            f'<figure><img src="{html.escape(fname)}" alt="{html.escape(caption)}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )

    def raw(self, markup: str) -> None:
        """Append trusted, already-escaped markup."""
        self._parts.append(markup)

    def attach(self, fname: str, data: bytes | str) -> None:
        """Write ``data`` (text is UTF-8 encoded) as ``fname`` beside the page."""
        self.files[fname] = data.encode() if isinstance(data, str) else data

    def render(self) -> str:
        """The page's HTML text."""
        return (
            "<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>{html.escape(self.title)}</title>"
            f"<style>{_CSS}</style></head><body><h1>{html.escape(self.title)}</h1>"
            + "\n".join(self._parts)
            + "</body></html>\n"
        )


def write_report_dir(page: HtmlPage, out_dir: str | os.PathLike) -> Path:
    """Write ``index.html`` and every attached file into ``out_dir`` atomically.

    Everything is written into a temporary folder beside ``out_dir`` which then
    replaces it, so a failure never leaves a half-written report.

    Parameters
    ----------
    page : HtmlPage
        The page and its files.
    out_dir : str or os.PathLike
        The report folder; its parent is created if needed, a previous folder replaced.

    Returns
    -------
    pathlib.Path
        The absolute path of the written ``index.html``.
    """
    out = Path(out_dir).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for fname, data in page.files.items():
            (tmp / fname).write_bytes(data)
        (tmp / "index.html").write_text(page.render(), encoding="utf-8")
        old = None
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=out.parent))
            os.replace(out, old / "x")
        os.replace(tmp, out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out / "index.html"
