"""Drawing a map into a matplotlib figure: layout, the scan as a density image, lines, objects
and their names, grid, scale bar and legend."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from mapkit.model import MapData, MapObject
from mapkit.render.base import _LEGEND_MIN_WIDTH, MAX_PIXELS, MIN_PIXELS, RenderError, Rendering
from mapkit.render.geometry import (
    _color,
    _data_extent,
    _finite,
    _is_degenerate,
    _label,
    _nice,
    _scale_label,
    _text,
)
from mapkit.render.kinds import (
    _AREA_FILL,
    _HATCH,
    _HATCH_PATTERN,
    _LEGEND_LABELS,
    _MARKERS,
    _RC,
    COLORS,
    object_kind,
    type_params,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["make_figure"]


# -- drawing -----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Layout:
    width: int
    height: int
    left: int
    bottom: int
    axes_w: int
    axes_h: int
    view: tuple[float, float, float, float]
    mpp: float  # metres per pixel


def _layout(
    extent: tuple[float, float, float, float] | None,
    width: int,
    height: int | None,
    *,
    thumbnail: bool,
    legend_px: int,
) -> _Layout:
    if extent is None:
        extent = (-1.0, -1.0, 1.0, 1.0)
    x0, y0, x1, y1 = extent
    pad = max(0.04 * max(x1 - x0, y1 - y0), 0.5)
    x0, y0, x1, y1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
    dx, dy = x1 - x0, y1 - y0
    if thumbnail:
        left = right = top = bottom = 1
    else:
        left, bottom, top, right = 62, 42, 34, 14 + legend_px
    axes_w = width - left - right
    if axes_w < 16:
        raise RenderError(
            f"a width of {width} px leaves no room for the map; use at least "
            f"{left + right + 16} px or a thumbnail"
        )
    if height is None:
        tallest = 1.0 if thumbnail else 1.6  # taller maps get room at the sides
        axes_h = round(min(max(axes_w * dy / dx, 0.35 * axes_w), tallest * axes_w))
        if not thumbnail:
            axes_h = max(axes_h, 260)
        height = axes_h + top + bottom
        if height > MAX_PIXELS:
            raise RenderError(f"the picture would be {height} px high; give --height")
    axes_h = height - top - bottom
    if axes_h < 16:
        raise RenderError(f"a height of {height} px leaves no room for the map")
    mpp = max(dx / axes_w, dy / axes_h)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    hw, hh = axes_w * mpp / 2, axes_h * mpp / 2
    view = (cx - hw, cy - hh, cx + hw, cy + hh)
    return _Layout(width, height, left, bottom, axes_w, axes_h, view, mpp)


def _density_image(
    points_mm: np.ndarray[Any, Any], lay: _Layout, resolution_mm: float
) -> np.ndarray[Any, Any] | None:
    """An RGBA image, one pixel per screen pixel of the map area, dark where points are."""
    if len(points_mm) == 0:
        return None
    x0, y0, _, _ = lay.view
    scale = 1.0 / (lay.mpp * 1000.0)  # pixels per mm
    ix = np.floor((points_mm[:, 0] - x0 * 1000.0) * scale).astype(np.int64)
    iy = np.floor((points_mm[:, 1] - y0 * 1000.0) * scale).astype(np.int64)
    ok = (ix >= 0) & (ix < lay.axes_w) & (iy >= 0) & (iy < lay.axes_h)
    flat = np.zeros(lay.axes_w * lay.axes_h, dtype=bool)
    flat[iy[ok] * lay.axes_w + ix[ok]] = True
    occ = flat.reshape(lay.axes_h, lay.axes_w)
    # Zoomed in beyond the map's grid: draw each point as a cell of the map's resolution.
    k = min(round(resolution_mm * scale), 9) if resolution_mm > 0 else 1
    if k > 1:
        from scipy.ndimage import binary_dilation

        occ = binary_dilation(occ, structure=np.ones((k, k), dtype=bool))
    rgba = np.zeros((lay.axes_h, lay.axes_w, 4), dtype=np.uint8)
    r, g, b = (int(COLORS["points"][i : i + 2], 16) for i in (1, 3, 5))
    rgba[occ] = (r, g, b, 255)
    return rgba


def _darker(color: str, f: float = 0.6) -> str:
    """A darker shade of ``#rrggbb`` (for text on a light fill of that colour)."""
    r, g, b = (int(int(color[i : i + 2], 16) * f) for i in (1, 3, 5))
    return f"#{r:02x}{g:02x}{b:02x}"


#: Where a name may go beside its anchor, in points: (dx, dy, horizontal alignment), tried in order.
_NAME_SPOTS = (
    (5, 3, "left"),
    (5, -10, "left"),
    (-5, 3, "right"),
    (-5, -10, "right"),
    (0, 7, "center"),
    (0, -14, "center"),
)


def _place_names(
    fig: Figure,
    ax: Axes,
    lay: _Layout,
    names: list[tuple[int, float, float, str, str]],
    fontsize: float,
    markers: np.ndarray[Any, Any],
) -> int:
    """Write names beside their anchors without overlapping each other or the object markers.

    Each name tries six spots (right/left and above/below, then centred above or below); a name
    that fits nowhere is left out,
    so a crowded map stays readable. Returns how many names were left out.
    """
    from matplotlib.font_manager import FontProperties

    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    prop = FontProperties(size=fontsize)
    px_per_pt = fig.dpi / 72.0
    pad = 0.1 * fontsize * px_per_pt + 1  # the box's pad, plus a pixel of air
    W, H = lay.width, lay.height
    taken = np.zeros((H + 1, W + 1), dtype=bool)
    # The map area's pixel box; names must stay inside it.
    ax0, ay0 = lay.left, lay.bottom
    ax1, ay1 = lay.left + lay.axes_w, lay.bottom + lay.axes_h
    if len(markers):
        px = ax.transData.transform(markers)
        for x, y in px[np.isfinite(px).all(axis=1)].astype(int):  # a few pixels around each
            taken[max(y - 4, 0) : max(y + 5, 0), max(x - 4, 0) : max(x + 5, 0)] = True
    anchors = ax.transData.transform(np.asarray([(n[1], n[2]) for n in names], dtype=float))
    # A light box rather than a stroked halo keeps names as text in SVG and PDF (searchable).
    box = {"boxstyle": "square,pad=0.1", "facecolor": "white", "edgecolor": "none", "alpha": 0.7}
    hidden = 0
    for (_, x, y, text, color), (axp, ayp) in zip(names, anchors, strict=True):
        label = _text(text)
        # Text metrics once per name; the spots' boxes follow arithmetically (baseline-aligned).
        w, h, d = renderer.get_text_width_height_descent(label, prop, ismath=False)
        for dx, dy, ha in _NAME_SPOTS:
            left = axp + dx * px_per_pt - {"left": 0.0, "center": w / 2, "right": w}[ha]
            base = ayp + dy * px_per_pt
            x0, y0 = math.floor(left - pad), math.floor(base - d - pad)
            x1, y1 = math.ceil(left + w + pad), math.ceil(base - d + h + pad)
            if x0 < ax0 or y0 < ay0 or x1 > ax1 or y1 > ay1:
                continue
            if not taken[y0:y1, x0:x1].any():
                taken[y0:y1, x0:x1] = True
                ax.annotate(
                    label,
                    (x, y),
                    xytext=(dx, dy),
                    textcoords="offset points",
                    ha=ha,
                    fontsize=fontsize,
                    color=color,
                    zorder=8,
                    bbox=box,
                    parse_math=False,
                    gid="name",
                    annotation_clip=True,
                )
                break
        else:
            hidden += 1
    return hidden


def _draw(
    fig: Figure,
    m: MapData,
    *,
    lay: _Layout,
    objects: list[tuple[int, MapObject]],
    show_points: bool,
    show_lines: bool,
    show_names: bool,
    thumbnail: bool,
    legend: bool,
    title: str | None,
) -> int:
    """Draw everything; returns how many names were left out for lack of room."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Polygon
    from matplotlib.ticker import MultipleLocator

    W, H = lay.width, lay.height
    ax = fig.add_axes((lay.left / W, lay.bottom / H, lay.axes_w / W, lay.axes_h / H))
    x0, y0, x1, y1 = lay.view
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_facecolor("white")
    small = 6.0 if thumbnail else 7.5
    handles: list[Any] = []

    # Scan points: one image whose pixels are the screen's pixels.
    n_points = sum(s.num_points for s in m.scans)
    if show_points and n_points:
        pts = np.concatenate([s.points for s in m.scans]) if len(m.scans) > 1 else m.points
        res = max((s.resolution for s in m.scans), default=0)
        img = _density_image(pts, lay, float(res))
        if img is not None:
            ax.imshow(
                img,
                origin="lower",
                extent=(x0, x1, y0, y1),
                interpolation="nearest",
                zorder=1,
                aspect="auto",
                gid="points",
            )
            handles.append(
                Line2D(
                    [],
                    [],
                    ls="",
                    marker="s",
                    ms=4,
                    color=COLORS["points"],
                    label=f"points ({n_points:,})",
                )
            )
    # LINES: one collection.
    n_lines = sum(s.num_lines for s in m.scans)
    if show_lines and n_lines:
        segs: Any = np.concatenate([s.lines for s in m.scans]).reshape(-1, 2, 2) / 1000.0
        ax.add_collection(
            LineCollection(segs, colors=COLORS["lines"], linewidths=0.9, zorder=2, gid="lines")
        )
        handles.append(Line2D([], [], color=COLORS["lines"], lw=1, label=f"lines ({n_lines:,})"))

    decl = m.declared_types()
    params = type_params(m)
    by_kind: dict[str, list[tuple[int, MapObject]]] = {}
    for i, o in objects:
        by_kind.setdefault(object_kind(m, o, decl), []).append((i, o))

    # Names to write, by priority (0 first): (priority, x, y, text, colour).
    names: list[tuple[int, float, float, str, str]] = []
    arrow_len = (14 if thumbnail else 22) * lay.mpp

    # Rectangles: forbidden areas hatched, sectors in their declared colour.
    rect_types: dict[tuple[str, str], tuple[str, int]] = {}
    for kind in ("sector", "home_area", "forbidden_area"):
        for i, o in by_kind.get(kind, []):
            corners = np.asarray(o.corners()) / 1000.0
            key: tuple[str, str]
            name_color = color = COLORS[kind]
            if kind == "forbidden_area":
                ax.add_patch(
                    Polygon(
                        corners,
                        closed=True,
                        facecolor=_AREA_FILL,
                        edgecolor=_HATCH,
                        hatch=_HATCH_PATTERN,
                        lw=0,
                        zorder=3,
                    )
                )
                patch = Polygon(
                    corners,
                    closed=True,
                    facecolor="none",
                    edgecolor=color,
                    lw=1.2,
                    zorder=4,
                    gid=f"object:{i}",
                )
                key = (kind, _LEGEND_LABELS[kind])
                name_color = COLORS["forbidden_name"]
            elif kind == "home_area":
                patch = Polygon(
                    corners,
                    closed=True,
                    facecolor="none",
                    edgecolor=color,
                    lw=1.4,
                    ls="--",
                    zorder=4,
                    gid=f"object:{i}",
                )
                key = (kind, _LEGEND_LABELS[kind])
            else:
                color = _color(params.get(o.type, {}).get("Color0"), COLORS["sector"])
                patch = Polygon(
                    corners,
                    closed=True,
                    facecolor=color,
                    alpha=0.25,
                    edgecolor=color,
                    lw=1.0,
                    zorder=3,
                    gid=f"object:{i}",
                )
                key = (kind + ":" + o.type, _label(o.type))
                name_color = _darker(color)
            ax.add_patch(patch)
            rect_types[key] = (color, rect_types.get(key, (color, 0))[1] + 1)
            if o.name:
                c = corners.mean(axis=0)
                names.append((4, c[0], c[1], o.name, name_color))
    for (rect_kind, type_label), (color, count) in rect_types.items():
        label = f"{type_label} ({count})"
        if rect_kind == "forbidden_area":
            handles.append(
                Patch(facecolor=_AREA_FILL, edgecolor=color, hatch=_HATCH_PATTERN, label=label)
            )
        elif rect_kind == "home_area":
            handles.append(Patch(facecolor="none", edgecolor=color, ls="--", label=label))
        else:
            handles.append(Patch(facecolor=color, alpha=0.35, edgecolor=color, label=label))

    # Line objects: forbidden lines, boundaries of declared types (one collection per type).
    line_groups: dict[tuple[str, str], list[MapObject]] = {}
    for kind in ("boundary", "forbidden_line"):
        for _, o in by_kind.get(kind, []):
            line_groups.setdefault((kind, o.type), []).append(o)
    for (kind, typ), group in line_groups.items():
        segs = np.asarray([o.corners() for o in group]) / 1000.0  # (K, 2, 2) metres
        if kind == "forbidden_line":
            color, ls, label = COLORS[kind], "-", _LEGEND_LABELS[kind]
            lw = 1.3 if thumbnail else 2.2
        else:
            p = params.get(typ, {})
            color, lw, ls = _color(p.get("Color0"), COLORS["boundary"]), 1.4, "--"
            label = _label(typ)
            if p.get("Shape") == "Measure":
                for seg in segs:
                    length = float(np.hypot(*(seg[1] - seg[0])))
                    names.append((6, *seg.mean(axis=0), f"{length:.2f} m", _darker(color)))
        ax.add_collection(
            LineCollection(
                segs, colors=color, linewidths=lw, linestyles=ls, zorder=5, gid=f"{kind}:{typ}"
            )
        )
        handles.append(Line2D([], [], color=color, lw=lw, ls=ls, label=f"{label} ({len(group)})"))
        for o, seg in zip(group, segs, strict=True):
            if o.name:
                names.append((5, *seg.mean(axis=0), o.name, _darker(color)))

    # Point objects: one marker call and one arrow call per kind.
    markers: list[np.ndarray[Any, Any]] = []
    point_kinds = ("home", "dock", "goal_heading", "goal", "location", "other_point")
    for prio, kind in enumerate(point_kinds):
        group = [o for _, o in by_kind.get(kind, [])]
        if kind == "location":  # text labels (Shape=Label): the name only, no marker
            text_only = [o for o in group if params.get(o.type, {}).get("Shape") == "Label"]
            names.extend((3, o.x / 1000, o.y / 1000, o.name, "#202020") for o in text_only)
            group = [o for o in group if params.get(o.type, {}).get("Shape") != "Label"]
        if not group:
            continue
        xy = np.asarray([(o.x, o.y) for o in group]) / 1000.0
        markers.append(xy)
        color = COLORS[kind]
        size = (4 if thumbnail else 7) if kind != "home" else (6 if thumbnail else 10)
        ax.plot(
            xy[:, 0],
            xy[:, 1],
            ls="",
            marker=_MARKERS[kind],
            ms=size,
            mfc=color,
            mec="white",
            mew=0.8,
            zorder=6,
            gid=kind,
        )
        if kind in ("goal_heading", "dock", "home"):
            th = np.radians([o.theta for o in group])
            direction = np.column_stack([np.cos(th), np.sin(th)]) * arrow_len
            markers.extend(xy + f * direction for f in (0.35, 0.7, 1.0))  # keep names off arrows
            ax.quiver(
                xy[:, 0],
                xy[:, 1],
                arrow_len * np.cos(th),
                arrow_len * np.sin(th),
                angles="xy",
                scale_units="xy",
                scale=1,
                color=color,
                zorder=7,
                units="dots",
                width=1.6 if thumbnail else 2.2,
                headwidth=4,
                headlength=4.5,
                headaxislength=4,
                gid=f"{kind}-heading",
            )
        handles.append(
            Line2D(
                [],
                [],
                ls="",
                marker=_MARKERS[kind],
                ms=6,
                mfc=color,
                mec="white",
                label=f"{_LEGEND_LABELS[kind]} ({len(group)})",
            )
        )
        names.extend(
            (min(prio, 3), px, py, o.name, color)
            for o, (px, py) in zip(group, xy, strict=True)
            if o.name
        )

    hidden = 0
    if show_names and names and not thumbnail:
        names.sort(key=lambda n: n[0])
        hidden = _place_names(
            fig, ax, lay, names, small, np.concatenate(markers) if markers else np.zeros((0, 2))
        )

    if thumbnail:
        ax.set_axis_off()
        return hidden

    # Grid and ticks in metres, a scale bar, a legend and a title.
    step = _nice((x1 - x0) / 8)
    ax.xaxis.set_major_locator(MultipleLocator(step))
    ax.yaxis.set_major_locator(MultipleLocator(step))
    ax.grid(True, color="#d0d0d0", lw=0.5, zorder=0)
    ax.set_axisbelow(True)
    ax.tick_params(labelsize=7.5, length=3)
    ax.set_xlabel("x (m)", fontsize=8, labelpad=2)
    ax.set_ylabel("y (m)", fontsize=8, labelpad=2)
    _scale_bar(ax, lay)
    if title:
        ax.set_title(_text(title), fontsize=9.5, loc="left", pad=6, parse_math=False)
    if legend and handles:
        fig.legend(
            handles=handles,
            loc="upper left",
            fontsize=7.5,
            frameon=False,
            bbox_to_anchor=((lay.left + lay.axes_w + 10) / W, (lay.bottom + lay.axes_h) / H),
            borderaxespad=0,
            handlelength=1.8,
            labelspacing=0.6,
        )
    return hidden


def _scale_bar(ax: Axes, lay: _Layout) -> None:
    from matplotlib.offsetbox import AnchoredOffsetbox, AuxTransformBox, TextArea, VPacker
    from matplotlib.patches import Rectangle

    x0, _, x1, _ = lay.view
    length = _nice((x1 - x0) / 5)
    bar = AuxTransformBox(ax.transData)
    h = 4 * lay.mpp
    for k in range(4):  # alternating black/white quarters, like a map's scale bar
        bar.add_artist(
            Rectangle(
                (k * length / 4, 0),
                length / 4,
                h,
                facecolor="black" if k % 2 == 0 else "white",
                edgecolor="black",
                lw=0.6,
            )
        )
    label = TextArea(_scale_label(length), textprops={"fontsize": 7.5})
    box = VPacker(children=[label, bar], align="center", pad=0, sep=2)
    anchored = AnchoredOffsetbox(loc="lower left", child=box, pad=0.4, borderpad=0.6, frameon=True)
    anchored.patch.set_facecolor("white")
    anchored.patch.set_alpha(0.8)
    anchored.patch.set_edgecolor("#b0b0b0")
    anchored.set_zorder(9)
    anchored.set_gid("scalebar")
    ax.add_artist(anchored)


def _visible_objects(m: MapData) -> list[tuple[int, MapObject]]:
    """The objects drawn, with their index in ``m.objects`` (the ``object:<i>`` gid)."""
    return [(i, o) for i, o in enumerate(m.objects) if _finite(o) and not _is_degenerate(o)]


def make_figure(
    m: MapData,
    *,
    width: int = 1600,
    height: int | None = None,
    dpi: float = 100,
    show_names: bool = True,
    show_points: bool = True,
    show_lines: bool = True,
    legend: bool = True,
    thumbnail: bool = False,
    title: str | None = None,
    _pyplot: bool = False,
) -> tuple[Figure, Rendering]:
    """Draw a map on a new matplotlib figure (Agg canvas, no pyplot).

    Args:
        m: The map.
        width: Picture width in pixels.
        height: Picture height in pixels (default: from the map's shape, at most 1.5 x the width
            of the map area).
        dpi: Dots per inch (text sizes are in points, so a higher dpi gives larger text).
        show_names: Write object names.
        show_points: Draw the scan points.
        show_lines: Draw the LINES.
        legend: Draw a legend to the right of the map (not in pictures under 560 px wide).
        thumbnail: A bare picture: no axes, grid, legend, title, names or scale bar.
        title: Title above the map (default: the file's name and category; ``""`` for none).

    Returns:
        The figure and a :class:`Rendering` describing it (``path`` and ``format`` ``None``).

    Raises:
        RenderError: When the size is out of range or leaves no room for the map.
    """
    for what, v in (("width", width), ("height", height)):
        if v is not None and not MIN_PIXELS <= v <= MAX_PIXELS:
            raise RenderError(f"{what} must be between {MIN_PIXELS} and {MAX_PIXELS} px, got {v}")
    if not 10 <= dpi <= 1200:
        raise RenderError(f"dpi must be between 10 and 1200, got {dpi}")
    objects = _visible_objects(m)
    legend = legend and not thumbnail and width >= _LEGEND_MIN_WIDTH
    lay = _layout(
        _data_extent(m, [o for _, o in objects]),
        int(width),
        None if height is None else int(height),
        thumbnail=thumbnail,
        legend_px=170 if legend else 0,
    )
    if title is None:
        src = os.path.basename(m.provenance.source) if m.provenance else ""
        title = f"{src}  ({m.category})" if src else m.category
    import matplotlib

    with matplotlib.rc_context(_RC):
        if _pyplot:
            import matplotlib.pyplot as plt

            fig = plt.figure(figsize=(lay.width / dpi, lay.height / dpi), dpi=dpi)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            fig = Figure(figsize=(lay.width / dpi, lay.height / dpi), dpi=dpi)
            FigureCanvasAgg(fig)
        fig.patch.set_facecolor("white")
        hidden = _draw(
            fig,
            m,
            lay=lay,
            objects=objects,
            show_points=show_points,
            show_lines=show_lines,
            show_names=show_names,
            thumbnail=thumbnail,
            legend=legend,
            title=title or None,
        )
    return fig, Rendering(None, None, lay.width, lay.height, float(dpi), lay.view, lay.mpp, hidden)
