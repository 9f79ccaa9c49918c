"""A DEM with nodata holes (voids: NaN, or a nodata value as SRTM writes them) in every algorithm that
takes a DEM: no traceback, the holes counted in the log, and a point on a hole either left out and
counted or refused naming the DEM and saying it lies on its holes (harness: hostile.py).

The DEMs are the simulator's own with square holes (6 DEM pixels, about 180 m) over about 3 % of it, and
holes under chosen points (a GCP, an image point, a road's vertex): as NaN (Float32, nodata NaN) and as
-32768 (Int16, nodata -32768). The matching algorithms have theirs beside their other hostile cases
(tests/qgis/test_hostile_matching.py for matchgcps, tests/qgis/test_hostile_matchtie.py for matchtiepoints).
"""
from __future__ import annotations

import csv

import numpy as np
import pytest
from osgeo import gdal, ogr, osr

import processing
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from tests.support.control_lines import roads  # noqa: F401 (the fixture)
from tests.support.dems import blob_holes, read_dem, with_holes
from tests.support.hostile import assert_refused, no_unraisable
from tests.support.ortho_compare import read_band, saved_cut
from tests.support.processing import RecordingFeedback

gdal.UseExceptions()
KINDS = {"NaN": None, "nodata -32768": -32768}


def _holes_under(dem_path, lon, lat, share: float = 0.03) -> np.ndarray:
    """Random square holes over ``share`` of the DEM, and a 5 x 5 pixel hole under each (lon, lat)."""
    z, gt, _ = read_dem(dem_path)
    mask = blob_holes(z.shape, share, seed=1)
    for x, y in zip(np.atleast_1d(lon), np.atleast_1d(lat)):
        j, i = int((x - gt[0]) / gt[1]), int((y - gt[3]) / gt[5])
        mask[max(i - 2, 0):i + 3, max(j - 2, 0):j + 3] = True
    return mask


def _log(feedback: RecordingFeedback) -> str:
    return "\n".join(feedback.infos + feedback.warnings)


def _run(alg: str, params: dict) -> RecordingFeedback:
    feedback = RecordingFeedback()
    with no_unraisable():
        processing.run(alg, params, feedback=feedback)
    return feedback


@pytest.fixture(scope="module")
def scene_inputs(simulated, tmp_path_factory) -> dict:
    """The simulated scene's GCPs, the image and ground point of GCP G1 (the holes sit under it), and
    the DEMs with holes."""
    folder = tmp_path_factory.mktemp("holes")
    with open(simulated["GCPS"]) as f:
        rows = list(csv.DictReader(f))
    g1 = next(r for r in rows if r["id"] == "G1")
    lon, lat = float(g1["lon"]), float(g1["lat"])
    mask = _holes_under(simulated["DEM"], lon, lat)
    dems = {k: with_holes(simulated["DEM"], folder / f"dem_{k.split()[0]}.tif", mask, v) for k, v in KINDS.items()}
    (folder / "pixels.csv").write_text(f"id,col,row\n1,{g1['col']},{g1['row']}\n2,6000.5,6000.5\n3,2000.5,9000.5\n")
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(folder / "ground.gpkg"))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    layer = ds.CreateLayer("ground", srs, ogr.wkbPoint)
    for x, y in ((lon, lat), (lon + 0.05, lat - 0.05)):
        feature = ogr.Feature(layer.GetLayerDefn())
        feature.SetGeometry(ogr.CreateGeometryFromWkt(f"POINT ({x} {y})"))
        layer.CreateFeature(feature)
    ds = layer = None
    return {"folder": folder, "dems": dems, "G1": (lon, lat)}


@pytest.fixture(scope="module")
def cut_inputs(tmp_path_factory) -> dict:
    """A rendered 120-row cut of a CBERS-02B scene (cut.json, raw.tif) and its DEM with holes, some of
    them inside the cut's footprint."""
    folder = tmp_path_factory.mktemp("holes_cut")
    scene_path, raw, dem_path = saved_cut(folder, seed=6, rows=120)
    scene = load_scene(scene_path)
    cols = np.linspace(500, scene.cameras[0].cols - 500, 7)
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem(cols, np.full(cols.size, 60.0), Dem(dem_path, "geoid")))
    mask = _holes_under(dem_path, lon, lat)
    dems = {k: with_holes(dem_path, folder / f"dem_{k.split()[0]}.tif", mask, v) for k, v in KINDS.items()}
    return {"scene": scene_path, "raw": raw, "dem": dem_path, "dems": dems}


@pytest.mark.parametrize("kind", KINDS)
def test_footprint(simulated, scene_inputs, tmp_path, kind):
    """Points of the outline on holes are left out, counted; the area is the clean DEM's."""
    def area(dem):
        out = processing.run("pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "DEM": dem,
                                                     "DEM_DATUM": "geoid", "OUTPUT": "memory:"})["OUTPUT"]
        return float(next(out.getFeatures())["area_km2"])
    feedback = RecordingFeedback()
    out = processing.run("pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "DEM": scene_inputs["dems"][kind],
                                                 "DEM_DATUM": "geoid", "OUTPUT": "memory:"}, feedback=feedback)
    holey = float(next(out["OUTPUT"].getFeatures())["area_km2"])
    assert holey == pytest.approx(area(simulated["DEM"]), rel=1e-3)
    assert "points of the image outline (" in _log(feedback) and "on its nodata holes): the outline runs without " \
                                                                "them" in _log(feedback)


@pytest.mark.parametrize("kind", KINDS)
def test_imagetoground(simulated, scene_inputs, tmp_path, kind):
    """The image point whose line of sight meets the DEM only on a hole is left out, counted and named."""
    feedback = _run("pushbroom:imagetoground", {"SCENE": simulated["TRUE_SCENE"],
                                                "INPUT": str(scene_inputs["folder"] / "pixels.csv"),
                                                "DEM": scene_inputs["dems"][kind], "DEM_DATUM": "geoid",
                                                "OUTPUT": str(tmp_path / "ground.gpkg")})
    ds = ogr.Open(str(tmp_path / "ground.gpkg"))
    assert sorted(f.GetField("id") for f in ds.GetLayer(0)) == ["2", "3"]
    assert "gives no height for 1 of 3 points (1 on its nodata holes): their lines of sight meet it only there; " \
           "those points are left out (feature ids 1)" in _log(feedback)


@pytest.mark.parametrize("kind", KINDS)
def test_groundtoimage(simulated, scene_inputs, tmp_path, kind):
    """A ground point without Z on a hole: refused, naming the DEM, the hole and the point."""
    dem = scene_inputs["dems"][kind]
    assert_refused("pushbroom:groundtoimage", {
        "SCENE": simulated["TRUE_SCENE"], "INPUT": str(scene_inputs["folder"] / "ground.gpkg"), "DEM": dem, "DEM_DATUM": "geoid",
        "OUTPUT": str(tmp_path / "image.gpkg")},
        "INPUT", f"DEM {dem} gives no height for 1 of 2 points (1 on its nodata holes)", "feature ids",
        watch=[scene_inputs["folder"], tmp_path])


@pytest.mark.parametrize("kind", KINDS)
def test_importgcps(simulated, scene_inputs, tmp_path, kind):
    """GCP G1 on a hole, heights from the DEM: refused, naming the DEM, the hole and G1."""
    dem = scene_inputs["dems"][kind]
    assert_refused("pushbroom:importgcps", {
        "SCENE": simulated["ONBOARD_SCENE"], "INPUT_FILE": simulated["GCPS"], "HEIGHT_SOURCE": "dem",
        "DEM": dem, "DEM_DATUM": "geoid", "OUTPUT": str(tmp_path / "gcps.gpkg")},
        f"DEM {dem} gives no height for 1 of", "(1 on its nodata holes): point(s) G1", watch=[tmp_path])


@pytest.mark.parametrize("kind", KINDS)
def test_importlines(roads, tmp_path, kind):  # noqa: F811
    """A road vertex on a hole, heights from the DEM: refused, naming the DEM and the hole."""
    result, _ = roads
    ds = ogr.Open(str(result.lines))
    feature = next(iter(ds.GetLayer("ground_lines")))
    vertex = feature.GetGeometryRef().GetPoint(0)
    mask = _holes_under(result.dem, vertex[0], vertex[1], share=0.0)
    dem = with_holes(result.dem, tmp_path / "dem_holes.tif", mask, KINDS[kind])
    assert_refused("pushbroom:importlines", {
        "SCENE": str(result.onboard_scene), "INPUT": f"{result.lines}|layername=ground_lines",
        "IMAGE_LINES": f"{result.lines}|layername=image_lines", "HEIGHT_SOURCE": "dem", "DEM": dem,
        "DEM_DATUM": "geoid", "OUTPUT": str(tmp_path / "lines.gpkg")},
        f"DEM {dem} gives no height for", "on its nodata holes)", watch=[tmp_path])


@pytest.mark.parametrize("kind", KINDS)
def test_exportrpc(cut_inputs, tmp_path, kind):
    """Sample rays on holes are left out of the height range, counted; the RPC is written."""
    feedback = _run("pushbroom:exportrpc", {"SCENE": cut_inputs["scene"], "DEM": cut_inputs["dems"][kind],
                                            "DEM_DATUM": "geoid", "OUTPUT": str(tmp_path / "cut_RPC.TXT")})
    assert (tmp_path / "cut_RPC.TXT").is_file()
    assert "points of a 33 x 33 grid over its image (" in _log(feedback) and "on its nodata holes); the height " \
                                                                            "range is taken from the others" \
        in _log(feedback)


@pytest.mark.parametrize("kind", KINDS)
def test_orthorectify(cut_inputs, tmp_path, kind):
    """The pixels on holes are nodata, counted as the footprint's pixels on the DEM's holes."""
    dem = cut_inputs["dems"][kind]
    feedback = _run("pushbroom:orthorectify", {"INPUT": cut_inputs["raw"], "SCENE": cut_inputs["scene"], "DEM": dem,
                                               "DEM_DATUM": "geoid", "RESOLUTION": 10.0,
                                               "OUTPUT": str(tmp_path / "ortho.tif")})
    assert f"DEM: DEM {dem} gives no height for " in _log(feedback)
    assert "output pixels of the image's footprint (" in _log(feedback) and "on its nodata holes)" in _log(feedback)
    assert "image positions within" in _log(feedback)


@pytest.mark.parametrize("kind", KINDS)
def test_sensorcorrect(cut_inputs, tmp_path, kind):
    """The virtual image's pixels whose lines of sight meet the DEM only on holes are nodata, counted."""
    dem = cut_inputs["dems"][kind]
    feedback = _run("pushbroom:sensorcorrect", {"INPUT": cut_inputs["raw"], "SCENE": cut_inputs["scene"], "DEM": dem,
                                                "DEM_DATUM": "geoid", "OUTPUT": str(tmp_path / "sc.tif"),
                                                "OUTPUT_SCENE": str(tmp_path / "sc.json")})
    assert f"DEM: DEM {dem} gives no height for " in _log(feedback)
    assert "pixels of the image (" in _log(feedback) and "on its nodata holes): their lines of sight meet it only " \
                                                        "there; those pixels are nodata" in _log(feedback)
    assert 0 < np.mean(read_band(str(tmp_path / "sc.tif")) == 0) < 0.2
