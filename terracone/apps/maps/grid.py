"""The raster grid of a map: cell size from the pushes' spacing, cells aligned to it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["Grid", "MAX_CELLS", "choose_grid", "nice_size", "push_spacing"]

#: Most cells of a default grid (the cell size grows to stay under it).
MAX_CELLS = 1_000_000


@dataclass(frozen=True)
class Grid:
    """A north-up grid of square cells in the map CRS.

    Attributes
    ----------
    west, north : float
        The outer edges of the first column and row [m].
    resolution : float
        Cell size [m].
    width, height : int
        Columns and rows (row 0 is the northernmost).
    """

    west: float
    north: float
    resolution: float
    width: int
    height: int

    @property
    def transform(self) -> tuple[float, float, float, float, float, float]:
        """The affine transform (a, b, c, d, e, f) of rasterio: x = a col + b row + c."""
        return (self.resolution, 0.0, self.west, 0.0, -self.resolution, self.north)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(west, south, east, north) [m]."""
        r = self.resolution
        return (self.west, self.north - self.height * r, self.west + self.width * r, self.north)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """x and y [m] of every cell centre, arrays of shape (height, width)."""
        r = self.resolution
        xs = self.west + (np.arange(self.width) + 0.5) * r
        ys = self.north - (np.arange(self.height) + 0.5) * r
        return np.meshgrid(xs, ys)


def push_spacing(x: np.ndarray, y: np.ndarray) -> float:
    """Median distance [m] from each push to its nearest other push at another place."""
    pts = np.unique(np.column_stack([x, y]).round(3), axis=0)
    d, _ = cKDTree(pts).query(pts, k=2)
    return float(np.median(d[:, 1]))


def nice_size(v: float) -> float:
    """The largest of 1, 2, 2.5, 5 x 10^k not above ``v``."""
    e = math.floor(math.log10(v))
    for m in (5.0, 2.5, 2.0, 1.0):
        if m * 10.0**e <= v * (1 + 1e-9):
            return m * 10.0**e
    return 10.0**e  # pragma: no cover


def choose_grid(x: np.ndarray, y: np.ndarray, resolution: float | None = None) -> tuple[Grid, str]:
    """The grid over the pushes, one cell beyond them on each side, and how its size was chosen.

    The default cell is half the median distance between neighbouring
    pushes, rounded down to 1, 2, 2.5 or 5 x 10^k m, larger where the grid
    would exceed :data:`MAX_CELLS` cells.  Cell edges are multiples of the
    cell size.
    """
    spacing = push_spacing(x, y)
    if resolution is None:
        res = nice_size(spacing / 2.0)
        note = f"default: half the median distance between neighbouring pushes ({spacing:.4g} m)"
    else:
        if not resolution > 0:
            raise ValueError(f"--resolution must be > 0 (got {resolution:g})")
        res, note = float(resolution), "given with --resolution"
    area = (np.ptp(x) + 2 * res) * (np.ptp(y) + 2 * res)
    if area / res**2 > MAX_CELLS:
        if resolution is not None:
            raise ValueError(
                f"--resolution {res:g} m gives {area / res**2:.3g} cells over the pushes; "
                f"at most {MAX_CELLS:,} (give a larger cell)"
            )
        res = nice_size(math.sqrt(area / MAX_CELLS)) * 2
        note += f", enlarged to stay under {MAX_CELLS:,} cells"
    west = math.floor(x.min() / res) * res - res
    north = math.ceil(y.max() / res) * res + res
    width = int(math.ceil((x.max() + res - west) / res))
    height = int(math.ceil((north - (y.min() - res)) / res))
    return Grid(west, north, res, width, height), note
