"""The heightfield soil's update for many simulators at once: one vectorised NumPy pass.

``HeightfieldSoil.update_many`` hands the soils of the default options (footprint intake,
no mouth tally, edge resistance) here; each soil belongs to its own simulator (its own
pile, bucket pose and material). What ``HeightfieldSoil.update`` computes for one soil
in a few dozen small NumPy calls, this pass computes for all of them in one set of calls
on stacked arrays: the bucket polygons in the world, the footprints' grid windows (padded
to the largest window), the candidate cells and their intersection with the polygons'
edges, and the cutting edges' depth samples.

Each soil's numbers are exactly those of its own ``update``, bit for bit:

- elementwise arithmetic runs in the same order of operations (NumPy rounds every
  float64 element on its own, so stacking changes no element's value);
- the small matrix products are stacked per simulator, and NumPy hands a stack to BLAS
  one matrix at a time with the strides the matrix has alone;
- minima and maxima are exact, whatever order they are taken in;
- every sum over a soil's cells is taken per soil, on an array of the shape it has alone
  (NumPy's pairwise summation groups terms by position), and the depth samples are added
  one after another, as ``update`` adds them;
- the scalar formulas (spill, FEE force, breakout) and the writes into each MuJoCo model
  run per soil, through the soil's own methods.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .heightfield import HeightfieldSoil

# ``HeightfieldSoil.layout_row`` columns: per-soil constants of the grid and material
X0, Y0, DX, DY, NCOL, NROW, HALF_WIDTH, DENSITY, CELL_AREA = range(9)
LIVE_SPAN_M = 1e-9  # an edge shorter than this along the heading is seen end-on: no cell
SIDES = np.array([-1.0, 1.0])  # left and right of the bucket's centre line


def update_heightfields(
    soils: Sequence[HeightfieldSoil], dts: Sequence[float], *, margin_m: float
) -> None:
    """``soil.update(dt)`` for each of ``soils`` (default options, bucket polygons with the
    same number of corners), computed together. ``margin_m``: the candidate margin along
    the heading (``CANDIDATE_MARGIN_M``)."""
    n = len(soils)
    machines = [soil.machine for soil in soils]
    heading = np.array([machine.heading() for machine in machines])
    pitch_rad = [machine.bucket_pitch() for machine in machines]
    bodies = [machine.bucket_body for machine in machines]
    rotation = np.array([soil._xmat[body] for soil, body in zip(soils, bodies, strict=True)])
    rotation = rotation.reshape(n, 3, 3)
    hinge = np.array([soil._xpos[body] for soil, body in zip(soils, bodies, strict=True)])
    hold_m3 = _holding_volumes(soils, pitch_rad)
    layout = np.array([soil.layout_row for soil in soils])
    polygon = np.array([soil._polygon_local for soil in soils])  # (n, V, 3), bucket frame

    # the bucket's inside in the vertical plane through the hinge: (s along heading, z)
    world = hinge[:, None, :] + polygon @ rotation.transpose(0, 2, 1)
    s_poly = ((world[:, :, :2] - hinge[:, None, :2]) @ heading[:, :, None])[:, :, 0]
    z_poly = world[:, :, 2]

    load_m3 = np.array([soil.bucket_load_kg for soil in soils]) / layout[:, DENSITY]
    _intake(soils, layout, hinge, heading, s_poly, z_poly, hold_m3 - load_m3, margin_m)

    depth_m = _edge_depths(soils, layout, world[:, 1, :], heading).tolist()
    force_n, breakout_n = np.empty(n), np.empty(n)
    for k, soil in enumerate(soils):
        soil._spill(float(hold_m3[k]), dts[k])
        soil._depth_m = soil.resistance_depth_m = depth_m[k]
        force_n[k] = soil._resistance_n(depth_m[k])
        breakout_n[k] = soil.breakout_force_n(depth_m[k])
    type(soils[0])._write_resistances(soils, rotation, heading, force_n, breakout_n)
    for soil in soils:
        soil._write_payload()


def _holding_volumes(soils: Sequence[HeightfieldSoil], pitch_rad: list[float]) -> np.ndarray:
    """The holding volume [m^3] of each bucket at its pitch: one ``np.interp`` per table
    (soils of one bucket and material share theirs), which interpolates each pitch as it
    would alone."""
    by_table: dict[int, list[int]] = {}
    for k, soil in enumerate(soils):
        by_table.setdefault(id(soil._holding_table), []).append(k)
    hold_m3 = np.empty(len(soils))
    for members in by_table.values():
        table = soils[members[0]]
        pitches = [pitch_rad[k] for k in members]
        hold_m3[members] = np.interp(pitches, table._pitch_table, table._holding_table)
    return hold_m3


def _intake(
    soils: Sequence[HeightfieldSoil],
    layout: np.ndarray,
    hinge: np.ndarray,
    heading: np.ndarray,
    s_poly: np.ndarray,
    z_poly: np.ndarray,
    room_m3: np.ndarray,
    margin_m: float,
) -> None:
    """``HeightfieldSoil._intake`` of every soil: the material under each bucket's inside
    moves into the bucket, up to the room it has (``room_m3`` [m^3])."""
    hx, hy = heading[:, 0:1], heading[:, 1:2]
    lx, ly = -hy, hx  # lateral: the heading turned 90 deg to the left
    # footprint corners [soil, s_min | s_max, left | right]: the polygon's extent along the
    # heading, the bucket width across it
    extent = np.stack([s_poly.min(axis=1), s_poly.max(axis=1)], axis=1)
    across = SIDES * layout[:, HALF_WIDTH : HALF_WIDTH + 1]
    corner_x = hinge[:, 0:1, None] + (extent * hx)[:, :, None] + (across * lx)[:, None, :]
    corner_y = hinge[:, 1:2, None] + (extent * hy)[:, :, None] + (across * ly)[:, None, :]
    n = len(soils)
    low = np.stack([corner_x.reshape(n, 4).min(axis=1), corner_y.reshape(n, 4).min(axis=1)], 1)
    high = np.stack([corner_x.reshape(n, 4).max(axis=1), corner_y.reshape(n, 4).max(axis=1)], 1)
    origin, cell = layout[:, [X0, Y0]], layout[:, [DX, DY]]
    first = np.maximum(np.floor((low - origin) / cell).astype(np.int64), 0)  # col, row
    last = np.ceil((high - origin) / cell).astype(np.int64) + 1
    last = np.minimum(last, layout[:, [NCOL, NROW]].astype(np.int64))
    taking = np.flatnonzero((room_m3 > 0.0) & (first < last).all(axis=1))
    if taking.size == 0:
        return
    size = last[taking] - first[taking]  # (m, 2): the windows' columns and rows
    windows = np.full((taking.size, int(size[:, 1].max()), int(size[:, 0].max())), -np.inf)
    for j, k in enumerate(taking.tolist()):
        (c0, r0), (c1, r1) = first[k].tolist(), last[k].tolist()
        windows[j, : r1 - r0, : c1 - c0] = soils[k].heights[r0:r1, c0:c1]
    # a bucket above the pile's highest cell of its window takes nothing
    reach = windows.max(axis=(1, 2)) > z_poly[taking].min(axis=1)
    taking, windows, size = taking[reach], windows[reach], size[reach]
    if taking.size == 0:
        return

    sub, start = layout[taking], first[taking]
    row_index, col_index = np.arange(windows.shape[1]), np.arange(windows.shape[2])
    # the cells' centres relative to the hinge, as ``HeightfieldSoil`` computes them
    rel_x = sub[:, X0, None] + sub[:, DX, None] * (start[:, 0, None] + col_index)
    rel_y = sub[:, Y0, None] + sub[:, DY, None] * (start[:, 1, None] + row_index)
    rel_x, rel_y = rel_x - hinge[taking, 0, None], rel_y - hinge[taking, 1, None]
    rel_x, rel_y = rel_x[:, None, :], rel_y[:, :, None]
    hx, hy, lx, ly = (v[taking, :, None] for v in (hx, hy, lx, ly))
    s = rel_x * hx + rel_y * hy  # (m, rows, cols): along the heading
    candidate = np.abs(rel_x * lx + rel_y * ly) <= sub[:, HALF_WIDTH, None, None]
    # only cells within the polygon's extent along the heading can lie on one of its edges
    candidate &= s >= (extent[taking, 0] - margin_m)[:, None, None]
    candidate &= s <= (extent[taking, 1] + margin_m)[:, None, None]
    candidate &= (row_index < size[:, 1:2])[:, :, None]  # the padding holds no cell
    candidate &= (col_index < size[:, 0:1])[:, None, :]
    owner, _, _ = np.nonzero(candidate)  # each candidate's soil (index into ``taking``)
    if owner.size == 0:
        return

    # vertical extent of each bucket polygon at its candidate cells' s: intersect with
    # its edges, edge by edge in rows (edges seen end-on along the heading hold no cell)
    # (V, candidates) arrays in C order (``np.take``; ``a[:, owner]`` would be in F order):
    # NumPy reduces across their rows fast, along a short last axis slowly (~10x, measured)
    s_a, z_a = s_poly[taking].T, z_poly[taking].T  # (V, m)
    nxt = np.roll(np.arange(len(s_a)), -1)
    span, rise = s_a[nxt] - s_a, z_a[nxt] - z_a
    live = np.abs(span) >= LIVE_SPAN_M
    span = np.where(live, span, 1.0)
    t_edge = (s[candidate] - np.take(s_a, owner, axis=1)) / np.take(span, owner, axis=1)
    on_edge = (t_edge >= 0.0) & (t_edge <= 1.0) & np.take(live, owner, axis=1)
    z_at = np.take(z_a, owner, axis=1) + t_edge * np.take(rise, owner, axis=1)
    z_floor = np.where(on_edge, z_at, np.inf).min(axis=0)
    z_roof = np.where(on_edge, z_at, -np.inf).max(axis=0)
    inside = np.isfinite(z_floor)
    column = np.minimum(windows[candidate], z_roof) - z_floor
    given = np.where(inside, np.clip(column, 0.0, None), 0.0)

    ends = np.cumsum(np.bincount(owner, minlength=taking.size)).tolist()
    begin = 0
    for j, k in enumerate(taking.tolist()):
        end = ends[j]
        if end == begin:
            continue
        (c0, r0), (c1, r1) = first[k].tolist(), last[k].tolist()
        taken = np.zeros((r1 - r0, c1 - c0))
        taken[candidate[j, : r1 - r0, : c1 - c0]] = given[begin:end]
        begin = end
        soils[k]._take(taken, (slice(r0, r1), slice(c0, c1)), float(room_m3[k]))


def _edge_depths(
    soils: Sequence[HeightfieldSoil], layout: np.ndarray, edge: np.ndarray, heading: np.ndarray
) -> np.ndarray:
    """``HeightfieldSoil._edge_depth`` of every soil [m]: the mean depth of its cutting
    edge (``edge``: world x, y, z of each) below the pile one cell ahead of it."""
    offsets = np.array([soil._edge_offsets_list for soil in soils])  # (n, samples) [m]
    hx, hy = heading[:, 0:1], heading[:, 1:2]
    x0, y0, dx, dy = (layout[:, i : i + 1] for i in (X0, Y0, DX, DY))
    ahead_x, ahead_y = edge[:, 0:1] + hx * dx, edge[:, 1:2] + hy * dx
    cols = np.rint((ahead_x - hy * offsets - x0) / dx).astype(np.int64)
    rows = np.rint((ahead_y + hx * offsets - y0) / dy).astype(np.int64)
    on_grid = (cols >= 0) & (cols < layout[:, NCOL : NCOL + 1])
    on_grid &= (rows >= 0) & (rows < layout[:, NROW : NROW + 1])
    surface = np.zeros(offsets.shape)
    for k, soil in enumerate(soils):
        inside = on_grid[k]
        surface[k, inside] = soil.heights[rows[k, inside], cols[k, inside]]
    below = np.where(on_grid, np.maximum(surface - edge[:, 2:3], 0.0), 0.0)
    total = np.zeros(len(soils))
    for sample in range(offsets.shape[1]):  # one after another, as ``_edge_depth`` adds
        total = total + below[:, sample]
    return np.where(on_grid.any(axis=1), total / offsets.shape[1], 0.0)
