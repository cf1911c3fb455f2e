"""The picture of a site's mission: the polygons over the cells they became, and the route
MuJoCo flew over the map with what its camera saw. Drawn on a standalone matplotlib
``Figure`` (no pyplot), in the map's cells, the polygons carried there from the local frame.
"""

from __future__ import annotations

import io

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle

from cpp_mujoco.maps import GridMap
from cpp_mujoco.review.plots import END_COLOR, PATH_COLOR, START_COLOR, draw_map, map_legend
from cpp_mujoco.sites.raster import LocalSite
from cpp_mujoco.sites.route import FlownRoute

# each kind's outline: the map's own colours, darker, so a polygon reads over its cells
OUTLINES = {
    "target": "#1b5e20", "no-fly": "#8b0000", "landing": "#0d2a80", "obstacle": "#333333",
    "boundary": "black",
}  # fmt: skip


def _draw_polygons(ax, local: LocalSite, labels: bool) -> None:
    """Every feature's outline in cell coordinates (a cell centre is a whole number)."""
    cell = local.georef.cell_size
    for feature, geometry in local.features:
        for polygon in getattr(geometry, "geoms", [geometry]):
            for ring in (polygon.exterior, *polygon.interiors):
                x, y = np.asarray(ring.coords).T
                ax.plot(x / cell - 0.5, -y / cell - 0.5, color=OUTLINES[feature.kind],
                        lw=1.6 if labels else 0.9, ls="--" if feature.kind == "boundary"
                        else "-")  # fmt: skip
        if labels and feature.name and feature.kind != "boundary":
            p = geometry.representative_point()
            ax.annotate(feature.name, (p.x / cell - 0.5, -p.y / cell - 0.5), fontsize=7,
                        ha="center", va="center", color="white",
                        bbox={"fc": OUTLINES[feature.kind], "ec": "none", "alpha": 0.75,
                              "pad": 1.5})  # fmt: skip


def _draw_route(ax, route: FlownRoute) -> None:
    rows, cols = (np.array(v) for v in zip(*route.cells, strict=True))
    arrow = {"arrowstyle": "->", "color": PATH_COLOR, "lw": 1.0}
    for r0, c0, r1, c1 in zip(rows[:-1], cols[:-1], rows[1:], cols[1:], strict=True):
        ax.annotate("", (c1, r1), (c0, r0), arrowprops=arrow)
    ax.add_patch(Rectangle((cols[-1] - 0.4, rows[-1] - 0.4), 0.8, 0.8, fill=False,
                           ec=END_COLOR, lw=2.5, zorder=4))  # fmt: skip
    ax.plot(cols[0], rows[0], "o", ms=9, mfc=START_COLOR, mec="white", mew=1.5, zorder=5)


def _draw_site(ax, grid_map: GridMap, local: LocalSite) -> None:
    """The polygons, labelled, over the map they were rasterised to."""
    h, w = grid_map.shape
    draw_map(ax, grid_map)
    _draw_polygons(ax, local, labels=True)
    g = local.georef
    ax.set_title(
        f"{local.site.name}: {len(local.features)} polygons -> {h}x{w} cells of "
        f"{g.cell_size:g} m, heading {g.heading_deg:g}°",
        fontsize=9,
    )


def _finish(fig: Figure, axes, grid_map: GridMap, local: LocalSite, path: bool) -> Figure:
    """Every panel over the whole map; legends for the cells and the polygons' outlines."""
    h, w = grid_map.shape
    for ax in axes:
        ax.set_xlim(-0.5, w - 0.5)
        ax.set_ylim(h - 0.5, -0.5)
    map_legend(fig, path=path, ncol=6 if path else 4, obstacles=grid_map.has_obstacles)
    kinds = sorted({f.kind for f, _ in local.features})
    handles = [Line2D([], [], color=OUTLINES[k], lw=1.6, ls="--" if k == "boundary" else "-",
                      label=f"{k} polygon") for k in kinds]  # fmt: skip
    fig.legend(handles=handles, loc="outside upper center", ncol=min(len(kinds), 3 + 2 * path),
               fontsize=8, frameon=False)  # fmt: skip
    return fig


def site_plot(grid_map: GridMap, local: LocalSite) -> Figure:
    """The site's polygons over the map they were rasterised to: check it before planning."""
    h, w = grid_map.shape
    fig = Figure(figsize=(6, 5.6 * h / w + 1.4), layout="constrained")
    ax = fig.subplots()
    _draw_site(ax, grid_map, local)
    return _finish(fig, [ax], grid_map, local, path=False)


def mission_plot(grid_map: GridMap, local: LocalSite, route: FlownRoute, title: str) -> Figure:
    """Left: the site's polygons over the map they were rasterised to. Right: the route flown
    in MuJoCo, the target cells its camera saw lightened, start and landing marked."""
    h, w = grid_map.shape
    fig = Figure(figsize=(11, 5.6 * h / w + 1.2), layout="constrained")
    left, right = fig.subplots(1, 2)
    _draw_site(left, grid_map, local)
    draw_map(right, grid_map, route.seen)
    _draw_polygons(right, local, labels=False)
    _draw_route(right, route)
    right.set_title(title, fontsize=9)
    return _finish(fig, [left, right], grid_map, local, path=True)


def png_bytes(fig: Figure) -> bytes:
    """The figure as PNG bytes: drawn before any file is written, then written atomically."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    return buffer.getvalue()
