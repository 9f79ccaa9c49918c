"""core.measure.surface: the DEM's height where it has one, the estimated height in its holes, and
which ground points lie in a hole (off the DEM or on its nodata)."""
import numpy as np
import pytest
from pyproj import CRS

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.measure.surface import FilledSurface
from tests.support.dems import write_dem

WGS84 = CRS.from_epsg(4326).to_wkt()


@pytest.fixture
def holey(tmp_path) -> Dem:
    """A 0.01 degree DEM over (10..11 E, 45..46 N) at 300 + 100 * (lon - 10) m, a nodata hole
    over (10.40..10.60 E, 45.40..45.60 N)."""
    lon = 10.005 + 0.01 * np.arange(100)
    lat = 45.995 - 0.01 * np.arange(100)
    z = np.tile(300.0 + 100.0 * (lon - 10.0), (100, 1))
    hole = (np.abs(lon - 10.5) < 0.1)[None, :] & (np.abs(lat - 45.5) < 0.1)[:, None]
    z[hole] = -32768.0
    return Dem(write_dem(tmp_path / "dem.tif", z, (10.0, 0.01, 0.0, 46.0, 0.0, -0.01), WGS84, nodata=-32768.0),
               datum="ellipsoid")


def test_heights_where_the_dem_has_them_the_estimate_in_its_holes(holey):
    surface = FilledSurface(holey, 222.0)
    h = surface.height(np.array([10.2, 10.5, 10.8]), np.array([45.2, 45.5, 45.8]))
    np.testing.assert_allclose(h, [320.0, 222.0, 380.0], atol=1e-6)
    lo, hi = surface.height_range
    assert lo == 222.0 and hi == pytest.approx(399.5, abs=0.6)


def test_points_in_a_hole_or_off_the_dem_are_told_apart_from_the_rest(holey):
    surface = FilledSurface(holey, 222.0)
    ground = geodetic_to_ecef(np.array([10.2, 10.5, 12.0, 10.8]), np.array([45.2, 45.5, 45.5, 45.8]),
                              np.array([320.0, 350.0, 300.0, 380.0])).reshape(-1, 3)
    ground = np.vstack([ground, np.full((1, 3), np.nan)])
    assert surface.in_hole(ground).tolist() == [False, True, True, False, False]
    said = surface.missing(ground, "grid points")
    assert "gives no height for 2 of 4 grid points" in said and "1 off its extent" in said, said
    assert surface.missing(ground[[0, 3]], "grid points") == ""
