"""A minimal, dependency-free HTML page builder and atomic report-folder writer.

Every report folder :func:`write_report_dir` writes carries a marker file,
:data:`REPORT_MARKER` (``.bdft-report``: JSON with the kind ``"bdft-report"``, the
page title, the command that wrote it, the workbench version and the files of the
report). A folder is replaced only when it is a previous report of ours
(:func:`is_report_dir`): a user's file or folder at the report path is never
deleted.
"""

from __future__ import annotations

import html
import io
import json
import os
import shlex
import shutil
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from robust.errors import ParameterError
from robust.export import is_artifact_file
from robust.jsonio import current_umask
from robust.version import __version__

__all__ = [
    "HtmlPage",
    "REPORT_MARKER",
    "check_report_target",
    "is_report_dir",
    "write_report_dir",
    "fmt",
]

#: Name of the marker file inside every report folder written by :func:`write_report_dir`.
REPORT_MARKER = ".bdft-report"
#: Value of the marker's ``kind`` field.
REPORT_KIND = "bdft-report"
#: File types a report written before the marker existed may hold.
_LEGACY_SUFFIXES = (".html", ".png", ".csv", ".json")
#: Files the reports attached before the marker existed without naming them on the page.
_LEGACY_ATTACHMENTS = ("claims.json", "designs.json", "sweep.json")

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


def _read_marker(folder: Path) -> dict | None:
    marker = folder / REPORT_MARKER
    try:
        if not marker.is_file() or marker.stat().st_size > 2**20:
            return None
        obj = json.loads(marker.read_bytes().decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(obj, dict) or obj.get("kind") != REPORT_KIND:
        return None
    return obj


def _is_legacy_page(index: Path) -> bool:
    """An ``index.html`` rendered by :class:`HtmlPage` before report folders had a marker."""
    try:
        with open(index, "rb") as fh:
            head = fh.read(64 * 1024).decode("utf-8", errors="replace")
    except OSError:
        return False
    return head.startswith("<!DOCTYPE html><html><head><meta charset='utf-8'><title>") and (
        f"<style>{_CSS}</style>" in head
    )


def _foreign_entries(folder: Path) -> list[str] | None:
    """Entries of an existing folder that are not ours; None when it is not a report at all.

    A folder is a report of ours when it has a valid marker, or (written before the
    marker existed) an ``index.html`` rendered by :class:`HtmlPage`, or when it holds
    nothing but controller artifacts (``bdft design`` writes them into the default
    report folder). Entries the marker lists, the marker itself and controller
    artifacts are ours; in a report without a marker, ``index.html`` and the files of
    the types a report holds that the page names (or that the reports attach) are.
    """
    try:
        entries = sorted(os.listdir(folder))
    except OSError:
        return None
    if not entries:
        return []

    def plain(e: str) -> bool:
        return (folder / e).is_file() and not (folder / e).is_symlink()

    artifacts = {e for e in entries if plain(e) and is_artifact_file(folder / e)}
    marker = _read_marker(folder)
    if marker is not None:
        listed = marker.get("files")
        ours = {REPORT_MARKER} | (
            {f for f in listed if isinstance(f, str)} if isinstance(listed, list) else set()
        )
    elif "index.html" in entries and _is_legacy_page(folder / "index.html"):
        page = (folder / "index.html").read_text(encoding="utf-8", errors="replace")
        ours = {"index.html"} | {
            e
            for e in entries
            if Path(e).suffix.lower() in _LEGACY_SUFFIXES
            and (html.escape(e) in page or e in _LEGACY_ATTACHMENTS)
        }
    elif set(entries) == artifacts:
        return []
    else:
        return None
    return [e for e in entries if not ((e in ours and plain(e)) or e in artifacts)]


def is_report_dir(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a report folder of ours that :func:`write_report_dir` may replace.

    Parameters
    ----------
    path : str or os.PathLike
        A folder.

    Returns
    -------
    bool
        True for an empty folder, a folder of controller artifacts only, or a folder
        with a valid :data:`REPORT_MARKER` (or, written before the marker existed, an
        ``index.html`` rendered by :class:`HtmlPage`) that holds nothing but the
        report's files and controller artifacts; False for anything else (a file, a
        folder of the user's, a report folder the user has added files to).
    """
    folder = Path(path)
    if not folder.is_dir() or folder.is_symlink():
        return False
    return _foreign_entries(folder) == []


def check_report_target(out_dir: str | os.PathLike, *, option: str = "out_dir") -> Path:
    """Check that a report may be written to ``out_dir``, before any work is done.

    Parameters
    ----------
    out_dir : str or os.PathLike
        The report folder: it must not exist (its nearest existing ancestor must then
        be a writable folder), or be a previous report of ours (:func:`is_report_dir`)
        in a writable folder.
    option : str, optional
        Name of the option or parameter that gave ``out_dir``, used in messages
        (``"--out"`` on the command line).

    Returns
    -------
    pathlib.Path
        ``out_dir``, absolute (symbolic links of the parent resolved).

    Raises
    ------
    ParameterError
        If ``out_dir`` is an existing file, a folder that is not a report of ours,
        under a file, or in a folder that cannot be written; the message names
        ``option``, what was expected and what is there.
    """
    given = Path(out_dir)
    if str(out_dir) == "" or given.name in ("", ".", ".."):
        raise ParameterError(
            f"{option}: expected a report folder path with a name of its own; got {str(out_dir)!r}"
        )
    out = given.absolute().parent.resolve() / given.name
    expected = "a new folder or a previous bdft report folder"
    if out.is_symlink():
        raise ParameterError(
            f"{option}: expected {expected}; got {str(given)!r}, a symbolic link "
            "(not replaced; give the folder it points to)"
        )
    if out.exists():
        if not out.is_dir():
            raise ParameterError(
                f"{option}: expected {expected}; got {str(given)!r}, an existing file "
                "(not replaced)"
            )
        foreign = _foreign_entries(out)
        if foreign is None:
            raise ParameterError(
                f"{option}: expected {expected}; got {str(given)!r}, an existing folder that "
                f"is not a bdft report (no {REPORT_MARKER} marker); not replaced. Choose a "
                "new folder or remove it yourself"
            )
        if foreign:
            shown = ", ".join(foreign[:5]) + (" ..." if len(foreign) > 5 else "")
            raise ParameterError(
                f"{option}: expected {expected}; got {str(given)!r}, a report folder that also "
                f"holds files bdft did not write ({shown}); not replaced. Move them away first"
            )
    ancestor = out.parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ParameterError(
            f"{option}: expected a folder path; got {str(given)!r}, but {str(ancestor)!r} is a file"
        )
    try:
        with tempfile.TemporaryFile(dir=ancestor):
            pass  # tried, not guessed: permission bits do not tell for root or read-only mounts
    except OSError as exc:
        raise ParameterError(
            f"{option}: expected a folder bdft can write; got {str(given)!r}, but files "
            f"cannot be created in {str(ancestor)!r} ({exc.strerror or exc})"
        ) from None
    return out


def _artifacts_to_keep(out: Path, page: HtmlPage) -> list[str]:
    """Controller artifacts in a report folder about to be replaced: they move to the new one."""
    if not out.is_dir():
        return []
    return [
        e
        for e in sorted(os.listdir(out))
        if e not in page.files
        and e not in ("index.html", REPORT_MARKER)
        and (out / e).is_file()
        and not (out / e).is_symlink()
        and is_artifact_file(out / e)
    ]


def _process_command() -> str | None:
    if not sys.argv or not sys.argv[0]:
        return None
    return shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]])


def write_report_dir(
    page: HtmlPage, out_dir: str | os.PathLike, *, command: str | None = None
) -> Path:
    """Write ``index.html``, every attached file and the marker into ``out_dir`` atomically.

    Everything is written into a temporary folder beside ``out_dir`` which then
    replaces it, so a failure never leaves a half-written report (and the previous
    one stays). Only a previous report of ours is replaced
    (:func:`check_report_target`); controller artifacts in it (``bdft design``
    writes them into the default report folder) are kept in the new one. The new
    folder gets the usual mode (``0o777`` less the umask) and the marker
    :data:`REPORT_MARKER`.

    Parameters
    ----------
    page : HtmlPage
        The page and its files (plain file names: no folders, not ``index.html`` or
        the marker's name).
    out_dir : str or os.PathLike
        The report folder; its parent is created if needed, a previous report
        replaced.
    command : str, optional
        The command that wrote the report, recorded in the marker (default: this
        process's command line).

    Returns
    -------
    pathlib.Path
        The absolute path of the written ``index.html``.

    Raises
    ------
    ParameterError
        If ``out_dir`` is not a new folder or a previous report of ours, or an
        attached file name is not a plain file name.
    """
    for fname in page.files:
        if (
            not isinstance(fname, str)
            or fname in ("", ".", "..", "index.html", REPORT_MARKER)
            or "/" in fname
            or os.sep in fname
            or (os.altsep is not None and os.altsep in fname)
        ):
            raise ParameterError(
                f"report file name: expected a plain file name (no folder, not index.html or "
                f"{REPORT_MARKER}); got {fname!r}"
            )
    out = check_report_target(out_dir)
    marker = {
        "kind": REPORT_KIND,
        "format_version": 1,
        "title": page.title,
        "command": command if command is not None else _process_command(),
        "version": __version__,
        "files": sorted([*page.files, "index.html"]),
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    old = None
    try:
        for fname, data in page.files.items():
            (tmp / fname).write_bytes(data)
        (tmp / "index.html").write_text(page.render(), encoding="utf-8")
        (tmp / REPORT_MARKER).write_text(json.dumps(marker, indent=2) + "\n", encoding="utf-8")
        for kept in _artifacts_to_keep(out, page):
            shutil.copy2(out / kept, tmp / kept)
        os.chmod(tmp, 0o777 & ~current_umask())
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=out.parent))
            os.replace(out, old / "x")
        os.replace(tmp, out)
    except BaseException:
        if old is not None and (old / "x").exists() and not out.exists():
            os.replace(old / "x", out)  # put the previous report back
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return out / "index.html"
