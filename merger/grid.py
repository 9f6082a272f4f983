"""Ternary occupancy grids (unknown / free / occupied) with resolution and origin.

Conventions (DESIGN.md, ROS nav_msgs/OccupancyGrid):

* public values are int8: ``-1`` unknown, ``0`` free, ``100`` occupied;
* row-major, row 0 at the grid origin (lowest y), column 0 at the lowest x;
* ``origin`` is the world position (x, y) of the corner of cell (0, 0);
* the centre of cell (row r, col c) is ``origin + ((c + 0.5) * res, (r + 0.5) * res)``.

``OccupancyGrid.states`` holds *state codes* (uint8): :class:`Cell` (``Cell.UNKNOWN = 0``, ``Cell.FREE = 1``,
``Cell.OCCUPIED = 2``; the kernels' ``UNKNOWN_S``, ``FREE_S``, ``OCCUPIED_S`` are the same numbers), so
``grid.states == Cell.OCCUPIED`` selects the occupied cells. The ROS values are named apart
(``ROS_UNKNOWN = -1``, ``ROS_FREE = 0``, ``ROS_OCCUPIED = 100``): they are what :meth:`OccupancyGrid.to_ros`
gives, never what ``states`` holds. The order unknown < free < occupied is deliberate: superposition with
occupied priority of two known cells and max-pooling are then plain maxima.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

# ROS int8 values at the public boundary (OccupancyGrid.to_ros, map files): never in ``states``
ROS_UNKNOWN = -1
ROS_FREE = 0
ROS_OCCUPIED = 100


class Cell(IntEnum):
    """The state codes ``OccupancyGrid.states`` holds: ``grid.states == Cell.OCCUPIED``."""

    UNKNOWN = 0
    FREE = 1
    OCCUPIED = 2


# the same codes as numpy scalars, for the compiled kernels
UNKNOWN_S = np.uint8(Cell.UNKNOWN)
FREE_S = np.uint8(Cell.FREE)
OCCUPIED_S = np.uint8(Cell.OCCUPIED)

DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.196


def states_from_ros(data: np.ndarray, *, occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
                    free_thresh: float = DEFAULT_FREE_THRESH) -> np.ndarray:
    """ROS int8 occupancy (-1 unknown, 0..100 probability in percent) to state codes.

    A value ``v`` in 0..100 is occupied when ``v/100 > occupied_thresh``, free when
    ``v/100 < free_thresh``, unknown otherwise (map_server's trinary rule); -1 is unknown.
    """
    data = np.asarray(data)
    p = data.astype(np.float32) / 100.0
    out = np.zeros(data.shape, np.uint8)
    known = data >= 0
    out[known & (p < free_thresh)] = FREE_S
    out[known & (p > occupied_thresh)] = OCCUPIED_S
    return out


def ros_from_states(states: np.ndarray) -> np.ndarray:
    lut = np.array([ROS_UNKNOWN, ROS_FREE, ROS_OCCUPIED], np.int8)
    return lut[np.asarray(states, np.uint8)]


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """A ternary occupancy grid.

    Parameters
    ----------
    states : (H, W) uint8 array of state codes (``UNKNOWN_S``, ``FREE_S``, ``OCCUPIED_S``).
    resolution : cell size in metres.
    origin : world (x, y) of the corner of cell (0, 0), i.e. the lowest x and lowest y.
    """

    states: np.ndarray
    resolution: float = 0.05
    origin: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        s = np.asarray(self.states)
        if s.ndim != 2:
            raise ValueError(f"occupancy grid must be 2-D, got shape {s.shape}")
        if s.dtype != np.uint8:
            s = s.astype(np.uint8)
        if s.size and s.max() > 2:
            raise ValueError("state codes must be 0 (unknown), 1 (free) or 2 (occupied)")
        if not (self.resolution > 0):
            raise ValueError(f"resolution must be > 0, got {self.resolution}")
        object.__setattr__(self, "states", s)
        object.__setattr__(self, "origin", (float(self.origin[0]), float(self.origin[1])))
        object.__setattr__(self, "resolution", float(self.resolution))

    # --- construction -------------------------------------------------------------------
    @classmethod
    def from_ros(cls, data: np.ndarray, resolution: float = 0.05, origin=(0.0, 0.0), *,
                 occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
                 free_thresh: float = DEFAULT_FREE_THRESH) -> OccupancyGrid:
        """From a ROS int8 array (-1 unknown, 0..100), thresholded like map_server."""
        return cls(states_from_ros(data, occupied_thresh=occupied_thresh, free_thresh=free_thresh),
                   resolution, tuple(origin))

    @classmethod
    def from_probabilities(cls, p: np.ndarray, resolution: float = 0.05, origin=(0.0, 0.0), *,
                           occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
                           free_thresh: float = DEFAULT_FREE_THRESH) -> OccupancyGrid:
        """From occupancy probabilities in [0, 1]; NaN means never observed (unknown)."""
        p = np.asarray(p, np.float64)
        s = np.zeros(p.shape, np.uint8)
        with np.errstate(invalid="ignore"):
            s[p < free_thresh] = FREE_S
            s[p > occupied_thresh] = OCCUPIED_S
        return cls(s, resolution, tuple(origin))

    @classmethod
    def from_log_odds(cls, log_odds: np.ndarray, resolution: float = 0.05, origin=(0.0, 0.0), *,
                      occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
                      free_thresh: float = DEFAULT_FREE_THRESH) -> OccupancyGrid:
        """From log-odds l = log(p / (1 - p)); thresholds are given as probabilities."""
        lo = np.asarray(log_odds, np.float64)
        s = np.zeros(lo.shape, np.uint8)
        s[lo < _logit(free_thresh)] = FREE_S
        s[lo > _logit(occupied_thresh)] = OCCUPIED_S
        return cls(s, resolution, tuple(origin))

    @classmethod
    def unknown(cls, height: int, width: int, resolution: float = 0.05, origin=(0.0, 0.0)):
        return cls(np.zeros((height, width), np.uint8), resolution, tuple(origin))

    # --- views --------------------------------------------------------------------------
    def to_ros(self) -> np.ndarray:
        """ROS int8 array: -1 unknown, 0 free, 100 occupied (row 0 = lowest y)."""
        return ros_from_states(self.states)

    @property
    def height(self) -> int:
        return int(self.states.shape[0])

    @property
    def width(self) -> int:
        return int(self.states.shape[1])

    @property
    def shape(self) -> tuple[int, int]:
        return self.states.shape  # type: ignore[return-value]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) in metres."""
        ox, oy = self.origin
        return (ox, ox + self.width * self.resolution, oy, oy + self.height * self.resolution)

    def world_to_cell(self, xy) -> np.ndarray:
        """Continuous cell coordinates (col, row) of world points; integer part = containing cell."""
        xy = np.asarray(xy, np.float64)
        return (xy - np.asarray(self.origin)) / self.resolution

    def cell_center(self, row, col) -> np.ndarray:
        """World (x, y) of cell centres."""
        row = np.asarray(row, np.float64)
        col = np.asarray(col, np.float64)
        return np.stack([self.origin[0] + (col + 0.5) * self.resolution,
                         self.origin[1] + (row + 0.5) * self.resolution], axis=-1)

    def known_part(self) -> OccupancyGrid:
        """The smallest block of this grid holding every known cell, on the same cell lattice (itself
        when nothing can be cut). Every cell outside it is unknown, so resampling the block gives the
        same map as resampling the whole grid, on fewer cells."""
        box = known_bounds(self.states)
        if box is None:
            return self
        r0, r1, c0, c1 = box
        if (r0, c0, r1, c1) == (0, 0, self.height, self.width):
            return self
        return OccupancyGrid(self.states[r0:r1, c0:c1], self.resolution,
                             (self.origin[0] + c0 * self.resolution, self.origin[1] + r0 * self.resolution))

    def count(self) -> dict[str, int]:
        """Number of unknown, free and occupied cells."""
        b = np.bincount(self.states.ravel(), minlength=3)
        return {"unknown": int(b[0]), "free": int(b[1]), "occupied": int(b[2])}

    def __repr__(self) -> str:  # arrays make the default repr useless
        c = self.count()
        return (f"OccupancyGrid({self.height}x{self.width}, res={self.resolution:g} m, "
                f"origin=({self.origin[0]:g}, {self.origin[1]:g}), occupied={c['occupied']}, "
                f"free={c['free']})")


def known_bounds(known: np.ndarray) -> tuple[int, int, int, int] | None:
    """(first row, end row, first column, end column) of the non-zero cells of a 2-D array (states or a
    known mask); None when there is none."""
    rows = np.flatnonzero(known.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(known.any(axis=0))
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


def _logit(p: float) -> float:
    return float(np.log(p / (1.0 - p)))
