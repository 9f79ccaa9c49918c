"""core.runs.layers: where imported points take their heights, and the GeoPackage destination's check."""
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.files import OutputError
from pushbroom_adjust.core.runs.base import FilesInUse, Terrain
from pushbroom_adjust.core.runs.layers import PointHeights, check_gpkg, heights_of


def test_heights_from_z_take_the_datum_the_crs_says():
    assert heights_of(PointHeights("z"), "EPSG:4979").datum == "ellipsoid"
    assert heights_of(PointHeights("z", "geoid"), "EPSG:4326").datum == "geoid"
    with pytest.raises(InputError, match=r"points' CRS \(EPSG:4326\) does not say"):
        heights_of(PointHeights("z"), "EPSG:4326", "EPSG:4326")


def test_constant_and_dem_heights(th1):
    assert heights_of(PointHeights("constant", terrain=Terrain(height=250.0)), None).value == 250.0
    with pytest.raises(InputError, match="HEIGHT: 1e\\+06 m is not a terrain height"):
        heights_of(PointHeights("constant", terrain=Terrain(height=1e6)), None)
    with pytest.raises(InputError, match="no DEM was given"):
        heights_of(PointHeights("dem"), None)
    heights = heights_of(PointHeights("dem", terrain=Terrain(th1["DEM"], "geoid")), None)
    assert heights.datum == "geoid" and 0 < heights.dem.height_range[0] < heights.dem.height_range[1] < 9000


def test_the_destination_is_a_geopackage_that_replaces_no_input(tmp_path):
    with pytest.raises(InputError, match="GCP layers are written as GeoPackage"):
        check_gpkg(str(tmp_path / "g.csv"), "GCP layers", FilesInUse())
    with pytest.raises((InputError, OutputError), match="INPUT"):
        check_gpkg(str(tmp_path / "g.gpkg"), "GCP layers", FilesInUse({"INPUT": [str(tmp_path / "g.gpkg")]}))
    check_gpkg(str(tmp_path / "g.gpkg"), "GCP layers", FilesInUse())
