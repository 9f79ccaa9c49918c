"""Hostile input to pushbroom:snaplines: each case one bad input, refused with a message naming
the parameter at fault while the inputs and the output folder stay unchanged, or (a line where
the image shows no feature) snapped where it can with a warning saying how many vertices were
kept and why."""
from __future__ import annotations

import numpy as np
import pytest
from osgeo import gdal, ogr, osr

from pushbroom_adjust.core.observations.lines import ImageLines, write_gpkg

from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback

ROAD_COL = 100.5   # the bright band's centre (px) in the test image


def _image(path, rows=200, cols=200, blank=False):
    """An 8-bit image with noise and a bright 3 px band centred on col ROAD_COL (or one value)."""
    rng = np.random.default_rng(0)
    a = np.full((rows, cols), 60, np.uint8) if blank else (60 + rng.normal(0, 3, (rows, cols))).astype(np.uint8)
    if not blank:
        a[:, 99:102] = 200
    ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte)
    ds.GetRasterBand(1).WriteArray(a)
    ds = None
    return str(path)


@pytest.fixture
def files(tmp_path):
    lines = ImageLines(["R1"], "HRC", [0, 4], [102.0, 99.0, 102.5, 101.0], [30.0, 80.0, 130.0, 180.0], 2.0)
    write_gpkg(tmp_path / "lines.gpkg", image=lines)
    out = tmp_path / "out"
    out.mkdir()
    return {"image": _image(tmp_path / "raw.tif"), "lines": str(tmp_path / "lines.gpkg"), "out": out,
            "watch": [tmp_path / "raw.tif", tmp_path / "lines.gpkg", out]}


def _params(f, **extra):
    return {"INPUT": f["image"], "IMAGE_LINES": f["lines"], "OUTPUT": str(f["out"] / "snapped.gpkg"), **extra}


def _layer(path, wkt: str, geom_type, epsg: int | None = None):
    """A GeoPackage layer image_lines with one feature ``wkt`` (line_id R1), CRS ``epsg`` or none."""
    srs = None
    if epsg is not None:
        srs = osr.SpatialReference()
        srs.ImportFromEPSG(epsg)
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    lyr = ds.CreateLayer("image_lines", srs, geom_type)
    lyr.CreateField(ogr.FieldDefn("line_id", ogr.OFTString))
    f = ogr.Feature(lyr.GetLayerDefn())
    f.SetField("line_id", "R1")
    f.SetGeometry(ogr.CreateGeometryFromWkt(wkt))
    lyr.CreateFeature(f)
    ds = None
    return str(path)


CASES = {
    "an image of the wrong size": (lambda f, d: _params(f, INPUT=_image(d / "small.tif", rows=100, cols=100)),
                                   ["INPUT", "outside", "R1", "100 columns"]),
    "a blank image": (lambda f, d: _params(f, INPUT=_image(d / "blank.tif", blank=True)), ["INPUT", "blank"]),
    "a point layer as image lines": (lambda f, d: _params(f, IMAGE_LINES=_layer(
        d / "points.gpkg", "POINT (100 -50)", ogr.wkbPoint)),
                                     ["IMAGE_LINES"]),
    "image lines not in the pixel frame": (lambda f, d: _params(f, IMAGE_LINES=_layer(
        d / "geo.gpkg", "LINESTRING (10.1 45.2, 10.2 45.3)", ogr.wkbLineString, 4326)),
                                           ["IMAGE_LINES", "y > 0"]),
    "OUTPUT is the IMAGE_LINES file": (lambda f, d: _params(f, OUTPUT=f["lines"]), ["OUTPUT", "IMAGE_LINES"]),
    "OUTPUT not a GeoPackage": (lambda f, d: _params(f, OUTPUT=str(f["out"] / "snapped.shp")),
                                ["OUTPUT", "GeoPackage"]),
    "MODE by number": (lambda f, d: _params(f, MODE=1), ["MODE", "option number", "centre, edge"]),
    "MODE in capitals": (lambda f, d: _params(f, MODE="Centre"), ["MODE", "lower case"]),
    "a band wider than the search": (lambda f, d: _params(f, WIDTH=30.0, SEARCH=10.0), ["WIDTH", "2 * search"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_snaplines_input_is_refused(provider, files, tmp_path, case):
    make, texts = CASES[case]
    assert_refused("pushbroom:snaplines", make(files, tmp_path), *texts, watch=files["watch"])


def test_mode_by_number_is_refused_from_qgis_process(qgis_process, files):
    assert_refused_cli(qgis_process, "pushbroom:snaplines", _params(files, MODE=0), "MODE", "option number",
                       watch=files["watch"])


def test_a_line_beyond_the_feature_is_snapped_where_it_can_with_a_warning(provider, files, tmp_path):
    import processing
    lines = ImageLines(["R1"], "HRC", [0, 3], [102.0, 99.0, 160.0], [30.0, 80.0, 80.0], 2.0)  # the last: off road
    write_gpkg(tmp_path / "bent.gpkg", image=lines)
    feedback = RecordingFeedback()
    processing.run("pushbroom:snaplines", _params(files, IMAGE_LINES=str(tmp_path / "bent.gpkg")),
                   feedback=feedback)
    ds = ogr.Open(str(files["out"] / "snapped.gpkg"))
    feature = next(iter(ds.GetLayer("image_lines")))
    geom = feature.GetGeometryRef()
    cols = [geom.GetX(i) for i in range(geom.GetPointCount())]
    assert abs(cols[0] - ROAD_COL) < 0.2 and cols[2] == 160.0
    assert any("kept their position" in w for w in feedback.warnings)
