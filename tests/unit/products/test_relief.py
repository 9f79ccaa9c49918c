"""core.products.relief: the bound of a DEM's departure from the node grid's interpolation holds
against the departure measured at every output pixel, on a plane, a DEM with a 10 m wall finer
than the cells and one coarser than them; the per-pixel corrections are the rate times the
departure."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import ndimage

from pushbroom_adjust.core.dem import HeightGrid
from pushbroom_adjust.core.products.relief import ReliefNodes, cell_rates, departure_bound, relief_corrections

STEP = 16  # output px between nodes
NODES = (9, 11)


def dem_grid(scale: float, wall: float) -> tuple[HeightGrid, callable]:
    """A DEM (1 px = 1 node, step 1) under an output grid mapped onto it with ``scale`` DEM px per
    output px (slightly rotated): a tilted plane and a wall of ``wall`` m across it; and the map
    output px (i, j) -> DEM pixel coordinates (u, v)."""
    def to_dem(i, j):
        return 6.2 + scale * (j + 0.1 * i), 6.7 + scale * (i - 0.07 * j)
    u_max, v_max = to_dem(NODES[0] * STEP, NODES[1] * STEP)
    ny, nx = int(v_max + 0.2 * scale * NODES[1] * STEP) + 8, int(u_max) + 8
    y, x = np.mgrid[0:ny, 0:nx] + 0.5
    z = 400.0 + 0.3 * x - 0.2 * y + wall * (x + 0.6 * y > 0.55 * (nx + 0.6 * ny))
    return HeightGrid(z, 0, 0, 1), to_dem


def nodes(grid: HeightGrid, to_dem, rate: float = 0.0) -> ReliefNodes:
    i, j = np.meshgrid(np.arange(NODES[0]) * STEP, np.arange(NODES[1]) * STEP, indexing="ij")
    u, v = to_dem(i.astype(float), j.astype(float))
    zero = np.zeros(NODES)
    return ReliefNodes(u, v, grid.sample(u, v), zero + rate, zero, zero)


def measured_departure(grid: HeightGrid, to_dem) -> np.ndarray:
    """Per cell (na-1, nb-1): the largest |DEM - bilinear interpolation of the cell's corners| over
    its output pixels."""
    relief = nodes(grid, to_dem)
    f = np.arange(STEP + 1) / STEP
    s, t = f[:, None], f[None, :]
    out = np.zeros((NODES[0] - 1, NODES[1] - 1))
    for a in range(NODES[0] - 1):
        for b in range(NODES[1] - 1):
            z = relief.z[a:a + 2, b:b + 2]
            interp = z[0, 0] + (z[1, 0] - z[0, 0]) * s + (z[0, 1] - z[0, 0]) * t + \
                (z[1, 1] - z[1, 0] - z[0, 1] + z[0, 0]) * s * t
            u, v = to_dem(a * STEP + s * STEP + 0 * t, b * STEP + t * STEP + 0 * s)
            out[a, b] = np.abs(grid.sample(u, v) - interp).max()
    return out


@pytest.mark.parametrize("scale", [0.2, 0.05], ids=["dem finer than a cell", "dem coarser than a cell"])
def test_the_bound_holds_the_departure_everywhere(scale):
    grid, to_dem = dem_grid(scale, wall=10.0)
    bound = departure_bound(grid, nodes(grid, to_dem), STEP)
    truth = measured_departure(grid, to_dem)
    assert bound.shape == truth.shape
    assert np.all(bound >= truth - 1e-9)
    assert truth.max() > 1.0  # the wall crosses cells: the test has something to bound
    # cells two cells or more from the wall: the plane alone, bounded near 0 (not a blanket figure)
    away = ndimage.maximum_filter(truth, size=5) < 1e-6
    assert away.sum() > 10 and bound[away].max() < 1e-6


def test_a_plane_has_no_departure():
    grid, to_dem = dem_grid(0.2, wall=0.0)
    assert departure_bound(grid, nodes(grid, to_dem), STEP).max() < 1e-6


def test_a_dem_much_finer_than_the_output_pixels_is_corrected_throughout():
    grid, to_dem = dem_grid(1.0, wall=10.0)
    assert departure_bound(grid, nodes(grid, to_dem), STEP) is None
    assert departure_bound(grid, nodes(grid, to_dem), STEP, fine=True) is not None


def test_corrections_are_the_rate_times_the_departure():
    grid, to_dem = dem_grid(0.2, wall=10.0)
    relief = nodes(grid, to_dem, rate=0.05)
    cells = np.zeros((NODES[0] - 1, NODES[1] - 1), bool)
    cells[3, 4] = cells[5, 2] = True
    (ii, jj), (dcol, drow), left = relief_corrections(SimpleNamespace(grid_at=lambda u, v: grid), relief, cells,
                                                      STEP, ((NODES[0] - 1) * STEP, (NODES[1] - 1) * STEP))
    assert ii.size == 2 * STEP * STEP
    u, v = to_dem(ii.astype(float), jj.astype(float))
    a, b = ii // STEP, jj // STEP
    s, t = (ii % STEP) / STEP, (jj % STEP) / STEP
    z = relief.z
    interp = z[a, b] + (z[a + 1, b] - z[a, b]) * s + (z[a, b + 1] - z[a, b]) * t + \
        (z[a + 1, b + 1] - z[a + 1, b] - z[a, b + 1] + z[a, b]) * s * t
    np.testing.assert_allclose(dcol, 0.05 * (grid.sample(u, v) - interp), atol=1e-9)
    np.testing.assert_array_equal(drow, 0.0)
    assert np.all(left == 0.0)  # a constant rate: nothing second order is left
    assert cell_rates(relief).shape == cells.shape and np.all(cell_rates(relief) == 0.05)
