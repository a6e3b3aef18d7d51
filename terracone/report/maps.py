"""Report section of a ``terracone map`` directory, drawn from its rasters.

For each mapped quantity one figure of two panels read from its GeoTIFF
(rasterio): the median and the width of the 90% interval (hi - lo), with
the pushes of ``points.parquet`` on both; masked cells (beyond the
variogram's range) stay blank.  A table gives each quantity's variogram and
leave-one-out cross-validation, and the notes of ``map.json`` follow (no
calibration, no spatial structure, pushes left out).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from terracone.apps.maps.directory import read_map_directory
from terracone.report.html import figure_part, kv_part, list_part, table_part, text_part
from terracone.report.tables import Table

__all__ = ["map_document", "map_figure", "read_raster"]


def read_raster(path: str | Path) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """Bands (3, height, width) of a map GeoTIFF and its extent (west, east, south, north) [m]."""
    import rasterio

    with rasterio.open(path) as src:
        bands = src.read().astype(float)
        b = src.bounds
    return bands, (b.left, b.right, b.bottom, b.top)


def map_figure(tif: str | Path, points: np.ndarray, title: str, unit: str) -> Figure:
    """The median and the 90% interval width of a map GeoTIFF, with the pushes (x, y) [m]."""
    bands, extent = read_raster(tif)
    fig = Figure(figsize=(9.0, 4.2))
    FigureCanvasAgg(fig)
    panels = [
        (bands[0], f"median [{unit}]", "viridis"),
        (bands[2] - bands[1], f"90% interval width [{unit}]", "magma"),
    ]
    x0, y0 = extent[0], extent[2]
    ext = (0.0, extent[1] - x0, 0.0, extent[3] - y0)
    for k, (img, label, cmap) in enumerate(panels, 1):
        ax = fig.add_subplot(1, 2, k)
        im = ax.imshow(np.ma.masked_invalid(img), extent=ext, origin="upper", cmap=cmap)
        ax.plot(points[:, 0] - x0, points[:, 1] - y0, "k.", ms=3, label="pushes")
        ax.set_aspect("equal")
        ax.set_xlabel(f"east of {x0:.0f} [m]")
        ax.set_ylabel(f"north of {y0:.0f} [m]")
        ax.set_title(label, fontsize=9)
        fig.colorbar(im, ax=ax, shrink=0.8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def _table(quantities: Mapping[str, Any]) -> Table:
    rows = []
    for name, q in quantities.items():
        vg, cv = q.get("variogram") or {}, q.get("cross_validation") or {}
        rows.append(
            [
                name, q["units"], q["pushes"], vg.get("model", "not mapped"), vg.get("nugget"),
                vg.get("sill"), vg.get("range"), cv.get("rmse"),
                cv.get("mean_standardised_error"), cv.get("coverage_90"),
                (q.get("cells") or {}).get("masked"),
            ]
        )  # fmt: skip
    return Table(
        key="map",
        title="Variograms and leave-one-out cross-validation",
        columns=[
            ("quantity", ""),
            ("units", ""),
            ("pushes", ""),
            ("variogram", "model"),
            ("variogram", "nugget"),
            ("variogram", "sill"),
            ("variogram", "range [m]"),
            ("leave-one-out", "RMSE"),
            ("leave-one-out", "mean std. error"),
            ("leave-one-out", "90% coverage"),
            ("cells", "masked"),
        ],
        rows=rows,
        notes=[
            "nugget and sill in the kriged space (log of pressures, n itself); range: where the "
            "variogram reaches 95% of its sill (cells farther than it from every push are masked).",
            "leave-one-out: each push predicted from the others with the variogram held fixed; "
            "the mean standardised error should be near 0 and the coverage near 90%.",
        ],
    )


def map_document(directory: str | Path) -> dict[str, Any]:
    """Report document of a ``terracone map`` output directory (``map.json`` and its files)."""
    d = Path(directory)
    stored = read_map_directory(d)
    doc = stored.doc
    points = np.column_stack([stored.points["x"], stored.points["y"]])
    quantities = doc.get("quantities") or {}
    parts: list[dict[str, Any]] = [
        kv_part(
            {
                "map directory": str(d),
                "CRS": f"{doc.get('crs')} ({doc.get('crs_name')})",
                "cell size [m]": doc.get("resolution"),
                "located pushes": (doc.get("pushes") or {}).get("located"),
                "calibration": doc.get("calibration") or "none (bounds)",
            }
        ),
        text_part(
            "Ordinary kriging in log space of plate pressure and mean CI (n in its own units), "
            "with a fitted variogram whose nugget absorbs push-to-push variation and each push's "
            "estimation noise. Each cell shows the median and the width of the 90% interval of "
            "its local mean (the rasters also hold the wider band of the value at a point, "
            "nugget included); dots are the pushes."
        ),
        table_part(_table(quantities), sortable=False),
    ]
    for name, q in quantities.items():
        if not q.get("file") or not (d / q["file"]).exists():
            continue
        fig = map_figure(d / q["file"], points, f"{name}: {q.get('description', '')}", q["units"])
        caption = f"{name} ({q.get('description', '')}): median and 90% interval width"
        if q.get("message"):
            caption += f". {q['message']}"
        parts.append(figure_part(fig, caption + ".", alt=f"map of {name}"))
    if doc.get("notes"):
        parts.append(list_part(doc["notes"]))
    return {
        "title": "terracone report: terrain map",
        "meta": {"map": str(d), "command": "map"},
        "sections": [{"id": "map", "heading": "Map", "parts": parts}],
    }
