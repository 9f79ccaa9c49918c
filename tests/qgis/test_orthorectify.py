"""pushbroom:orthorectify in QGIS and from qgis_process, on a rendered cut of a simulated scene."""
import json
import re
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal
from qgis.core import QgsProcessingException, QgsProject, QgsRasterMinMaxOrigin

import processing
from pushbroom_adjust.core.formats.scene_json import save_scene
from pushbroom_adjust.simulation.block import simulate_block
from tests.support.ortho_compare import rendered_cameras, rendered_cut

from tests.support.processing import RecordingFeedback
from tests.support.qgis_process import run_json
from tests.unit.measure.test_pairmatching import MEMBERS


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    """(scene JSON, raw image, DEM) of a 400-row cut of a CBERS-02B scene, rendered."""
    folder = tmp_path_factory.mktemp("raw")
    scene, result, _, _ = rendered_cut(folder, seed=2, rows=400)
    save_scene(scene, folder / "cut.json")
    return str(folder / "cut.json"), str(folder / "raw.tif"), str(result.dem)


def test_orthorectify_with_processing_run(provider, raw, tmp_path):
    scene, image, dem = raw
    out = processing.run("pushbroom:orthorectify", {"INPUT": image, "SCENE": scene, "DEM": dem, "DEM_DATUM": "geoid",
                                                    "RESOLUTION": 5.0, "RESAMPLING": "cubic",
                                                    "OUTPUT": str(tmp_path / "ortho.tif")})["OUTPUT"]
    ds = gdal.Open(out)
    assert ds.GetGeoTransform()[1] == 5.0 and "UTM zone 50N" in ds.GetProjection()
    data = ds.GetRasterBand(1).ReadAsArray()
    # a 400-row cut is a thin strip across its bounding box: ~11 % of it is image
    assert 0.05 < np.mean(data > 0) < 0.3 and ds.GetRasterBand(1).GetNoDataValue() == 0


def test_bad_parameters_are_named(provider, raw, tmp_path):
    scene, image, dem = raw
    base = {"INPUT": image, "SCENE": scene, "DEM": dem, "OUTPUT": str(tmp_path / "o.tif")}
    with pytest.raises(QgsProcessingException, match="CRS: EPSG:4326 is not a projected CRS"):
        processing.run("pushbroom:orthorectify", {**base, "CRS": "EPSG:4326"})
    with pytest.raises(QgsProcessingException, match="OUTPUT: the orthoimage is written as GeoTIFF"):
        processing.run("pushbroom:orthorectify", {**base, "OUTPUT": str(tmp_path / "o.png")})
    with pytest.raises(QgsProcessingException, match="the raster is 12246 x 400 px but camera HRC"):
        processing.run("pushbroom:orthorectify", {**base, "SCENE": str(Path(scene).with_name("true_scene.json"))})
    with pytest.raises(QgsProcessingException, match="CRS: unknown CRS 'EPSG:999999'"):
        processing.run("pushbroom:orthorectify", {**base, "CRS": "EPSG:999999"})
    with pytest.raises(QgsProcessingException, match=r"cannot write .*o.tif: folder .*missing does not exist"):
        processing.run("pushbroom:orthorectify", {**base, "OUTPUT": str(tmp_path / "missing" / "o.tif")})
    nocrs = tmp_path / "nocrs.tif"
    src = gdal.Open(dem)
    copy = gdal.GetDriverByName("GTiff").CreateCopy(str(nocrs), src)
    copy.SetProjection("")
    copy = None
    with pytest.raises(QgsProcessingException, match="DEM: .*nocrs.tif: has no coordinate reference system"):
        processing.run("pushbroom:orthorectify", {**base, "DEM": str(nocrs)})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nocrs.tif"]


def test_a_dem_covering_part_of_the_scene_is_warned(provider, raw, tmp_path):
    """Without EXTENT the grid cannot be planned (an error naming the DEM); with an extent, the
    pixels without a height are nodata and a warning gives their share."""
    scene, image, dem = raw
    src = gdal.Open(dem)
    half = tmp_path / "west.tif"  # the western half of the DEM
    gdal.Translate(str(half), src, srcWin=[0, 0, src.RasterXSize // 2, src.RasterYSize])
    with pytest.raises(QgsProcessingException, match=r"DEM .*west.tif does not cover the scene"):
        processing.run("pushbroom:orthorectify", {"INPUT": image, "SCENE": scene, "DEM": str(half),
                                                  "OUTPUT": str(tmp_path / "o.tif")})
    full = processing.run("pushbroom:orthorectify", {"INPUT": image, "SCENE": scene, "DEM": dem, "RESOLUTION": 10,
                                                     "OUTPUT": str(tmp_path / "full.tif")})["OUTPUT"]
    ds = gdal.Open(full)
    g = ds.GetGeoTransform()
    extent = f"{g[0]},{g[0] + g[1] * ds.RasterXSize},{g[3] + g[5] * ds.RasterYSize},{g[3]} [EPSG:32650]"
    feedback = RecordingFeedback()
    processing.run("pushbroom:orthorectify", {"INPUT": image, "SCENE": scene, "DEM": str(half), "RESOLUTION": 10,
                                              "EXTENT": extent, "OUTPUT": str(tmp_path / "part.tif")},
                   feedback=feedback)
    said = [re.search(r"gives no height for (\d+) of (\d+) output pixels", w) for w in feedback.warnings
            if w.startswith(f"DEM: DEM {half} gives no height for")]
    assert said and said[0], feedback.warnings
    part_ds = gdal.Open(str(tmp_path / "part.tif"))  # held: a band outliving its dataset crashes GDAL
    part = part_ds.GetRasterBand(1).ReadAsArray()
    whole = ds.GetRasterBand(1).ReadAsArray()
    assert part.shape == whole.shape and 0.2 < np.mean(part > 0) / np.mean(whole > 0) < 0.8
    # the warning counts the footprint's pixels the partial DEM leaves empty
    empty, footprint = int(((whole > 0) & (part == 0)).sum()), int((whole > 0).sum())
    assert int(said[0][1]) == pytest.approx(empty, rel=2e-3) and int(said[0][2]) == pytest.approx(footprint, rel=2e-3)


def test_orthorectify_from_the_command_line(qgis_process, raw, tmp_path):
    scene, image, dem = raw
    results = run_json(qgis_process, "pushbroom:orthorectify", INPUT=image, SCENE=scene, DEM=dem, DEM_DATUM="geoid",
                        CRS="EPSG:32650", RESOLUTION=10, OUTPUT=tmp_path / "o.tif")
    ds = gdal.Open(results["OUTPUT"])
    assert ds.GetGeoTransform()[1] == 10.0 and ds.RasterCount == 1


@pytest.fixture(scope="module")
def three_line(tmp_path_factory):
    """(scene JSON, images in camera order, DEM) of a rendered 96-row cut of a TH-1 three-line scene."""
    folder = tmp_path_factory.mktemp("tlc")
    scene, result, _, _, images = rendered_cameras(folder, "th1_tlc", seed=5, rows=96)
    save_scene(scene, folder / "cut.json")
    return str(folder / "cut.json"), [images[k] for k in range(3)], str(result.dem)


def test_every_camera_in_one_run_equals_the_single_camera_runs(provider, three_line, tmp_path):
    scene, images, dem = three_line
    base = {"SCENE": scene, "DEM": dem, "DEM_DATUM": "geoid", "RESOLUTION": 40.0}
    fractions = []
    feedback = RecordingFeedback()
    feedback.progressChanged.connect(fractions.append)
    res = processing.run("pushbroom:orthorectify", {**base, "ALL_CAMERAS": True, "INPUTS": images,
                                                    "ORTHO_FOLDER": str(tmp_path / "all")}, feedback=feedback)
    names = ["ortho_NAD.tif", "ortho_FWD.tif", "ortho_BWD.tif"]
    assert res["ORTHOIMAGES"] == [str(tmp_path / "all" / n) for n in names]
    assert sorted(p.name for p in (tmp_path / "all").iterdir()) == sorted(names)
    assert fractions == sorted(fractions) and fractions[-1] == 100
    for camera, image, name in zip(("NAD", "FWD", "BWD"), images, names):
        single = processing.run("pushbroom:orthorectify", {**base, "INPUT": image, "CAMERA": camera,
                                                           "OUTPUT": str(tmp_path / name)})["OUTPUT"]
        assert Path(single).read_bytes() == (tmp_path / "all" / name).read_bytes(), name


def test_every_camera_from_the_command_line(qgis_process, three_line, tmp_path):
    scene, images, dem = three_line
    done = qgis_process("--json", "run", "pushbroom:orthorectify", "--", f"SCENE={scene}", f"DEM={dem}",
                        "RESOLUTION=40", "ALL_CAMERAS=true", *(f"INPUTS={i}" for i in images),
                        f"ORTHO_FOLDER={tmp_path}")
    assert done.returncode == 0, done.stdout + done.stderr
    results = json.loads(done.stdout)["results"]
    assert [Path(p).name for p in results["ORTHOIMAGES"]] == ["ortho_NAD.tif", "ortho_FWD.tif", "ortho_BWD.tif"]
    assert all(gdal.Open(p).GetGeoTransform()[1] == 40.0 for p in results["ORTHOIMAGES"])


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    """The rendered 2-strip block of four TH-1 cuts (tests/unit/measure/test_pairmatching.py)."""
    folder = tmp_path_factory.mktemp("block")
    simulate_block(MEMBERS, folder, seed=4, n_gcps=10, n_tie_points=20, render=True)
    return folder


def test_a_block_mosaic_is_loaded_stretched_and_its_overlaps_checked(provider, block, tmp_path):
    """SCENES with the onboard models: four orthoimages, the mosaic loaded into the project with its
    contrast stretched, and the log naming the five pairs that do not co-register."""
    names = [m.name for m in MEMBERS]
    params = {"SCENES": [str(block / n / "onboard_scene.json") for n in names],
              "INPUTS": [str(block / n / "image_NAD.tif") for n in names], "DEM": str(block / "dem.tif"),
              "DEM_DATUM": "geoid", "MOSAIC_ORDER": "given", "ORTHO_FOLDER": str(tmp_path / "mosaic")}
    feedback = RecordingFeedback()
    project = QgsProject.instance()
    out = processing.runAndLoadResults("pushbroom:orthorectify", params, feedback=feedback)
    assert out["MOSAIC"] == str(tmp_path / "mosaic" / "mosaic.vrt")
    assert out["ORTHOIMAGES"] == [str(tmp_path / "mosaic" / f"ortho_{n}.tif") for n in names]
    (layer,) = project.mapLayersByName("Mosaic")
    assert layer.source() == out["MOSAIC"]
    origin = layer.renderer().minMaxOrigin() if hasattr(layer.renderer(), "minMaxOrigin") else None
    assert origin is not None and origin.limits() == QgsRasterMinMaxOrigin.CumulativeCut
    assert any("5 of 5 overlapping pairs do not co-register" in line for line in feedback.warnings)
    assert sum(" px RMS (median " in line for line in feedback.infos) == 5
    project.removeMapLayer(layer)
    with pytest.raises(QgsProcessingException, match="SCENE and SCENES are both given"):
        processing.run("pushbroom:orthorectify", {**params, "SCENE": params["SCENES"][0]})
    with pytest.raises(QgsProcessingException, match="MOSAIC_ORDER: 'newest' is not a value|MOSAIC_ORDER"):
        processing.run("pushbroom:orthorectify", {**params, "MOSAIC_ORDER": "newest",
                                                  "ORTHO_FOLDER": str(tmp_path / "other")})
    assert not (tmp_path / "other").exists()
