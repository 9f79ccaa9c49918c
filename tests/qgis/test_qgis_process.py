"""End to end on the command line: qgis_process loads the plugin, lists its algorithms and runs
them on files. (Debian's /usr/bin/qgis_process wrapper is broken here; the binary is used.)"""
import csv
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import ogr, osr

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.products.footprint import footprints
from pushbroom_adjust.core.formats import load_scene

from tests.support.provider import ALGORITHMS
from tests.support.qgis_process import read_layer, run_json


def test_list_shows_the_algorithms(qgis_process):
    done = qgis_process("list")
    assert done.returncode == 0, done.stderr
    for alg_id in ALGORITHMS:
        assert alg_id in done.stdout, alg_id


def test_help_shows_parameter_help(qgis_process):
    done = qgis_process("help", "pushbroom:groundtoimage")
    assert done.returncode == 0, done.stderr
    assert "Z_DATUM" in done.stdout and "GDAL convention" in done.stdout


def test_run_footprint_from_the_command_line(qgis_process, simulated, tmp_path):
    out = tmp_path / "footprint.gpkg"
    results = run_json(qgis_process, "pushbroom:footprint", SCENE=simulated["TRUE_SCENE"], DEM=simulated["DEM"],
                        DEM_DATUM="geoid", SAMPLES=16, OUTPUT=out)
    assert Path(results["OUTPUT"].split("|")[0]) == out
    values, _ = read_layer(out, "camera", "area_km2")
    truth = footprints(load_scene(simulated["TRUE_SCENE"]), Dem(simulated["DEM"], "geoid"), samples_per_edge=16)
    assert list(values[:, 0]) == [fp.camera for fp in truth]
    assert np.allclose(values[:, 1].astype(float), [fp.area_km2 for fp in truth], rtol=1e-9)


def test_run_groundtoimage_from_the_command_line(qgis_process, simulated, tmp_path):
    scene = load_scene(simulated["TRUE_SCENE"])
    dem = Dem(simulated["DEM"], "geoid")
    cam = scene.cameras[0]
    col = np.linspace(0.5, cam.cols - 0.5, 7)
    row = np.linspace(cam.rows - 0.5, 0.5, 7)
    lon, lat, h = ecef_to_geodetic(scene.image_to_ground_dem(col, row, dem))
    points = _write_points(tmp_path / "points.gpkg", lon, lat, h)
    out = tmp_path / "image_points.gpkg"
    run_json(qgis_process, "pushbroom:groundtoimage", SCENE=simulated["TRUE_SCENE"], INPUT=points,
              Z_DATUM="ellipsoid", OUTPUT=out)
    values, _ = read_layer(out, "name", "col", "row", "in_image")
    assert list(values[:, 0]) == [f"p{i}" for i in range(7)]
    assert np.abs(values[:, 1].astype(float) - col).max() < 1e-4
    assert np.abs(values[:, 2].astype(float) - row).max() < 1e-4
    assert set(values[:, 3]) == {1}


def test_simulate_import_and_image_to_ground_chained_on_the_command_line(qgis_process, tmp_path):
    """Three-line preset, noise-free, with advanced settings in their user units (µrad)."""
    sim = run_json(qgis_process, "pushbroom:simulatescene", PRESET="th1_tlc", SEED=2, N_GCPS=30, IMAGE_NOISE=0,
                    CHECK_FRACTION=0.5, POSITION_BIAS=0, ATTITUDE_BIAS=100, OUTPUT_FOLDER=tmp_path / "sim")
    manifest = json.loads(Path(sim["MANIFEST"]).read_text())
    assert manifest["preset"] == "th1_tlc" and manifest["errors"]["position_bias"] == 0.0
    assert manifest["errors"]["attitude_bias"] == pytest.approx(1e-4)
    assert manifest["errors"]["attitude_drift"] == pytest.approx(5e-7)  # preset default kept
    # import against the true scene: noise-free measurements have zero a-priori residuals
    gcps = tmp_path / "gcps.gpkg"
    run_json(qgis_process, "pushbroom:importgcps", SCENE=sim["TRUE_SCENE"], INPUT_FILE=sim["GCPS"], Z_FIELD="h",
              Z_DATUM="ellipsoid", ROLE_FIELD="role", CAMERA_FIELD="camera", OUTPUT=gcps)
    values, _ = read_layer(gcps, "id", "camera", "role", "res_px", "col", "row")
    with open(sim["GCPS"]) as f:
        n_rows = sum(1 for _ in f) - 1
    assert len(values) == n_rows > 60 and set(values[:, 1]) == {"NAD", "FWD", "BWD"}
    assert np.sum(values[:, 2] == "check") > 0 and np.max(values[:, 3].astype(float)) < 1e-5
    # the nadir measurements back to the ground on the DEM land on the true points
    ground = tmp_path / "ground.gpkg"
    run_json(qgis_process, "pushbroom:imagetoground", SCENE=sim["TRUE_SCENE"], CAMERA="NAD", INPUT=gcps,
              DEM=sim["DEM"], DEM_DATUM="geoid", OUTPUT=ground)
    out, _ = read_layer(ground, "id", "camera", "lon", "lat")
    nad = out[:, 1] == "NAD"
    truth = {r["id"]: (float(r["lon_true"]), float(r["lat_true"]))
             for r in csv.DictReader(open(sim["GCPS"])) if r["camera"] == "NAD"}
    expected = np.array([truth[i] for i in out[nad, 0]])
    assert np.abs(out[nad, 2:4].astype(float) - expected).max() < 1e-8  # degrees: 1 mm


def test_a_failing_run_exits_non_zero_with_the_message(qgis_process, tmp_path):
    bad = tmp_path / "broken.json"
    bad.write_text('{"format": "pushbroom-scene", "version": 1')
    done = qgis_process("run", "pushbroom:footprint", "--", f"SCENE={bad}", f"OUTPUT={tmp_path / 'x.gpkg'}")
    assert done.returncode != 0
    assert "SCENE:" in done.stdout + done.stderr and "invalid JSON" in done.stdout + done.stderr


def _write_points(path, lon, lat, h) -> Path:
    """A GeoPackage of 3D points in EPSG:4979 with a 'name' field, written with OGR."""
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4979)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    layer = ds.CreateLayer("points", srs, ogr.wkbPoint25D)
    layer.CreateField(ogr.FieldDefn("name", ogr.OFTString))
    for i, (x, y, z) in enumerate(zip(lon, lat, h)):
        f = ogr.Feature(layer.GetLayerDefn())
        f.SetField("name", f"p{i}")
        g = ogr.Geometry(ogr.wkbPoint25D)
        g.AddPoint(float(x), float(y), float(z))
        f.SetGeometry(g)
        layer.CreateFeature(f)
    ds = None
    return path
