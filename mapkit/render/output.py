"""Writing pictures: :func:`render` to PNG, SVG or PDF (or a window), and the writer registered
for ``mapkit convert``."""

from __future__ import annotations

import dataclasses
import io
import os
from typing import Any

from mapkit._atomic import atomic_write
from mapkit._typing import PathLike
from mapkit.errors import UnsupportedFormatError
from mapkit.formats.registry import register_writer
from mapkit.model import MapData
from mapkit.render.base import FORMATS, RenderError, Rendering
from mapkit.render.figure import make_figure
from mapkit.render.kinds import _RC

__all__ = ["render"]


def _check_display() -> None:
    import matplotlib

    if os.name == "posix" and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RenderError(
            "cannot open a window: no display (DISPLAY is not set); write a file "
            "with -o OUT.png instead"
        )
    import matplotlib.pyplot as plt  # resolves the backend

    backend = plt.get_backend().lower()
    if backend in ("agg", "pdf", "svg", "ps", "pgf", "cairo", "template") or "inline" in backend:
        raise RenderError(
            f"cannot open a window: matplotlib has no interactive backend here "
            f"(it uses {matplotlib.get_backend()!r}; install a GUI toolkit, e.g. "
            f"Tk: apt install python3-tk python3-pil.imagetk); write a file with "
            f"-o OUT.png instead"
        )


def render(
    m: MapData,
    path: PathLike | None = None,
    *,
    show: bool = False,
    width: int = 1600,
    height: int | None = None,
    dpi: float = 100,
    show_names: bool = True,
    show_points: bool = True,
    show_lines: bool = True,
    legend: bool = True,
    thumbnail: bool = False,
    title: str | None = None,
) -> Rendering:
    """Draw a map to a PNG, SVG or PDF file (by the suffix of ``path``) and/or a window.

    The file is written atomically. PNG is exactly ``width`` x ``height`` pixels; SVG and PDF
    have the same size in points at ``dpi`` (``width * 72 / dpi``), with names kept as text in SVG.

    Args:
        m: The map.
        path: Output file (``.png``, ``.svg`` or ``.pdf``), or ``None`` with ``show=True``.
        show: Open a window with the picture (blocks until it is closed).
        width: Picture width in pixels.
        height: Picture height in pixels (default: from the map's shape).
        dpi: Dots per inch.
        show_names: Write object names.
        show_points: Draw the scan points.
        show_lines: Draw the LINES.
        legend: Draw a legend.
        thumbnail: A bare picture of the map only (see :func:`make_figure`).
        title: Title (default: file name and category; ``""`` for none).

    Returns:
        What was drawn and where.

    Raises:
        UnsupportedFormatError: When the suffix is not ``.png``, ``.svg`` or ``.pdf``.
        RenderError: When neither a path nor ``show`` is given, the size is out of range, or
            ``show`` is asked for where no window can be opened.
        OSError: When the file cannot be written.
    """
    fmt = None
    if path is not None:
        suffix = os.path.splitext(os.fspath(path))[1].lower()
        fmt = FORMATS.get(suffix)
        if fmt is None:
            raise UnsupportedFormatError(
                f"cannot draw {os.fspath(path)!r}: pictures are .png, .svg or .pdf, not "
                f"{suffix or '(no suffix)'!r}"
            )
    elif not show:
        raise RenderError("give an output file or show=True")
    if show:
        _check_display()
    opts = dict(
        width=width,
        height=height,
        dpi=dpi,
        show_names=show_names,
        show_points=show_points,
        show_lines=show_lines,
        legend=legend,
        thumbnail=thumbnail,
        title=title,
    )
    fig, info = make_figure(m, _pyplot=show, **opts)  # type: ignore[arg-type]
    if path is not None:
        import matplotlib

        buf = io.BytesIO()
        meta: dict[str, Any] = {"Software": "mapkit"} if fmt == "png" else {"Creator": "mapkit"}
        if fmt == "svg":
            meta["Date"] = None
        elif fmt == "pdf":
            meta["CreationDate"] = None
        with matplotlib.rc_context(_RC):
            fig.savefig(buf, format=fmt, dpi=dpi, metadata=meta, facecolor="white")
        atomic_write(path, buf.getvalue())
        info = dataclasses.replace(info, path=os.fspath(path), format=fmt)
    if show:
        import matplotlib.pyplot as plt

        plt.show()
        plt.close(fig)
    return info


def _writer(m: MapData, path: PathLike) -> str:
    r = render(m, path)
    kind = r.format.upper() if r.format else ""
    return f"wrote {os.fspath(path)} ({r.width}x{r.height} px {kind})"


for _suffix in FORMATS:
    register_writer(_suffix, _writer)
