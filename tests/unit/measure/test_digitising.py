"""Digitising control lines without a user interface: the display copy (core.measure.display), the line
editor, the nearest ground line and ground lines predicted into the image (core.measure.digitising)."""
import csv
from types import SimpleNamespace

import numpy as np
import pytest
from osgeo import gdal, ogr

from pushbroom_adjust.core.measure.digitising import LineEditor, PredictedLine, densify, nearest_line, predict_lines
from pushbroom_adjust.core.measure.display import (PIXEL_GEOTRANSFORM, check_image_size, read_display_source, write_display_vrt,
                          write_empty_lines)
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.observations.lines import read_image_lines
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.simulator import simulate
from tests.support.polylines import distances_to_polylines


@pytest.fixture(scope="module")
def roads(tmp_path_factory):
    """A CBERS-02B HRC scene with 6 simulated roads (all correct on the map)."""
    result = simulate("cbers02b_hrc", tmp_path_factory.mktemp("roads"), seed=5, n_gcps=12, n_lines=6)
    ds = ogr.Open(str(result.lines))
    ids, parts = [], []
    for feature in ds.GetLayerByName("ground_lines"):
        ids.append(feature["line_id"])
        parts.append(np.array(feature.GetGeometryRef().GetPoints()))
    with open(result.folder / "line_points.csv", newline="") as f:
        points = list(csv.DictReader(f))
    return {"result": result, "ids": ids, "parts": parts, "points": points}


def _raster(path, cols, rows, rpc=True):
    ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte)
    ds.GetRasterBand(1).WriteArray((np.arange(rows * cols).reshape(rows, cols) % 251).astype(np.uint8))
    if rpc:
        ds.SetMetadata({"LINE_OFF": "100", "SAMP_OFF": "150", "LAT_OFF": "10", "LONG_OFF": "20", "HEIGHT_OFF": "0",
                        "LINE_SCALE": "100", "SAMP_SCALE": "150", "LAT_SCALE": "0.1", "LONG_SCALE": "0.1",
                        "HEIGHT_SCALE": "100", "LINE_NUM_COEFF": " ".join(["0", "0", "1"] + ["0"] * 17),
                        "LINE_DEN_COEFF": " ".join(["1"] + ["0"] * 19),
                        "SAMP_NUM_COEFF": " ".join(["0", "1"] + ["0"] * 18),
                        "SAMP_DEN_COEFF": " ".join(["1"] + ["0"] * 19)}, "RPC")
    ds = None
    return path


# --- display copy --------------------------------------------------------------------------------
def test_display_copy_shows_the_raw_pixels_in_the_pixel_frame(tmp_path):
    raw = _raster(tmp_path / "raw.tif", 300, 200)
    before = raw.read_bytes()
    write_display_vrt(raw, tmp_path / "display.vrt", str(tmp_path / "scene.json"), "HRC")
    ds = gdal.Open(str(tmp_path / "display.vrt"))
    assert ds.GetGeoTransform() == PIXEL_GEOTRANSFORM
    assert not ds.GetMetadata("RPC") and ds.GetGCPCount() == 0
    assert "Pushbroom image pixels" in ds.GetSpatialRef().ExportToWkt()
    np.testing.assert_array_equal(ds.ReadAsArray(), gdal.Open(str(raw)).ReadAsArray())
    assert gdal.Open(str(raw)).GetMetadata("RPC")["LINE_OFF"] == "100" and raw.read_bytes() == before
    source = read_display_source(tmp_path / "display.vrt")
    assert (source.image, source.cols, source.rows, source.camera) == (str(raw), 300, 200, "HRC")
    assert source.scene == str(tmp_path / "scene.json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["display.vrt", "raw.tif"]


def test_display_copy_refuses_other_names_and_sizes(tmp_path):
    raw = _raster(tmp_path / "raw.tif", 300, 200, rpc=False)
    with pytest.raises(InputError, match="use a .vrt file name"):
        write_display_vrt(raw, tmp_path / "display.tif")
    with pytest.raises(InputError, match="300 x 200 pixels but camera HRC .* 12246 x 9000"):
        check_image_size(raw, SimpleNamespace(cols=12246, rows=9000, name="HRC"))
    assumed = SimpleNamespace(cols=12246, rows=9000, name="img", size_source="from the RPC's sample and line range; no "
                                                                         "image img.tif beside img_RPC.TXT")
    with pytest.raises(InputError, match=r"delivers 12246 x 9000 \(the scene's size 12246 x 9000 px was assumed: from "
                                         r"the RPC's sample and line range; no image img.tif beside img_RPC.TXT\)"):
        check_image_size(raw, assumed)
    with pytest.raises(InputError, match="missing.tif does not exist"):
        check_image_size(tmp_path / "missing.tif", SimpleNamespace(cols=1, rows=1, name="HRC"))
    (tmp_path / "text.tif").write_text("not a raster")
    with pytest.raises(InputError, match="text.tif is not a raster GDAL can read"):
        check_image_size(tmp_path / "text.tif", SimpleNamespace(cols=1, rows=1, name="HRC"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["raw.tif", "text.tif"]


@pytest.mark.parametrize("cols, rows, exact", [(300, 200, True), (3000, 2000, False)])
def test_a_display_copy_carries_the_images_statistics(tmp_path, cols, rows, exact):
    """Asked for statistics (as QGIS asks of every raster it loads), the display copy gives its own:
    nothing is computed on the raw image and nothing written beside it. Exact up to 1 Mpx; beyond, from
    whole 256 x 256 tiles spread over the image (here 24 of 96, flagged approximate: QGIS takes them as
    they are for rasters over 0.5 Mpx)."""
    raw = tmp_path / "raw.tif"
    gdal.Translate(str(raw), str(_raster(tmp_path / "striped.tif", cols, rows, rpc=False)), creationOptions=["TILED=YES"])
    (tmp_path / "striped.tif").unlink()
    write_display_vrt(raw, tmp_path / "display.vrt")
    ds = gdal.Open(str(tmp_path / "display.vrt"))
    band = ds.GetRasterBand(1)
    values = gdal.Open(str(raw)).ReadAsArray().astype(float)
    low, high, mean, std = band.GetStatistics(not exact, False)  # False: only what the VRT holds
    assert (low, high) == (values.min(), values.max())
    assert abs(mean - values.mean()) < (1e-9 if exact else 1.0) and abs(std - values.std()) < (1e-9 if exact else 1.0)
    assert (band.GetMetadataItem("STATISTICS_APPROXIMATE") == "YES") != exact
    band = ds = None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["display.vrt", "raw.tif"]


def test_empty_line_layer_has_the_image_lines_format(tmp_path):
    write_empty_lines(tmp_path / "lines.gpkg")
    ds = ogr.Open(str(tmp_path / "lines.gpkg"))  # kept: the layer lives only as long as its data source
    layer = ds.GetLayerByName("image_lines")
    assert layer.GetFeatureCount() == 0 and layer.GetGeomType() == ogr.wkbLineStringM
    names = [layer.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(layer.GetLayerDefn().GetFieldCount())]
    assert names == ["line_id", "camera", "sigma_px"]


# --- the editor ----------------------------------------------------------------------------------
def test_editor_adds_finishes_undoes_deletes_and_pairs(tmp_path):
    editor = LineEditor()
    for col, row in ((10, 20), (30, 40), (30, 40), (55.5, 61.25)):  # the repeated click is one vertex
        editor.add_vertex(col, row)
    assert editor.undo() == "vertex" and editor.current == [(10.0, 20.0), (30.0, 40.0)]
    assert editor.finish() == 0 and editor.selected == 0
    editor.add_vertex(100, 100)
    with pytest.raises(InputError, match="at least two vertices"):
        editor.finish()
    editor.add_vertex(120, 90)
    editor.add_vertex(140, 95)
    editor.finish()
    with pytest.raises(InputError, match=r"image line\(s\) 1, 2 are not paired"):
        editor.image_lines("HRC")
    editor.pair_selected("R2")
    editor.select(0)
    editor.pair_selected("R1")
    editor.add_vertex(1, 1)
    with pytest.raises(InputError, match="still being drawn"):
        editor.image_lines("HRC")
    assert editor.undo() == "vertex"
    lines = editor.image_lines("HRC")
    assert lines.line_id.tolist() == ["R1", "R2"] and lines.start.tolist() == [0, 2, 5]
    np.testing.assert_array_equal(lines.col, [10, 30, 100, 120, 140])
    np.testing.assert_array_equal(lines.row, [20, 40, 100, 90, 95])
    assert editor.delete_selected() and [line.line_id for line in editor.lines] == ["R2"]
    assert not editor.delete_selected()
    assert editor.undo() == "line" and editor.undo() == "" and editor.lines == []


def test_editor_refuses_pairing_without_a_selection():
    editor = LineEditor()
    with pytest.raises(InputError, match="select an image line first"):
        editor.pair_selected("R1")
    with pytest.raises(InputError, match="no image line to save"):
        editor.image_lines("HRC")
    with pytest.raises(InputError, match="there is no line 3"):
        editor.select(2)


# --- ground lines ---------------------------------------------------------------------------------
def test_nearest_line_is_the_nearest_segment_not_vertex():
    long_segment = np.array([[0.0, 0.0], [100.0, 0.0]])  # its vertices are far from the click
    short = np.array([[48.0, 5.0], [52.0, 5.0], [52.0, 9.0]])
    assert nearest_line([short, long_segment], 50.0, 1.0) == (1, 1.0)
    assert nearest_line([short, long_segment], 50.0, 4.0) == (0, 1.0)
    with pytest.raises(InputError, match="holds no lines"):
        nearest_line([], 0.0, 0.0)


def test_densify_keeps_the_vertices_and_bounds_the_spacing():
    part = np.array([[10.0, 45.0, 100.0], [10.001, 45.0, 110.0], [10.001, 45.002, 90.0]])
    dense = densify(part, 20.0)
    steps = np.hypot(np.diff(dense[:, 0]) * 111320.0 * np.cos(np.radians(45.0)), np.diff(dense[:, 1]) * 111320.0)
    assert steps.max() <= 20.0 + 1e-6 and len(dense) == 4 + 12 + 1
    for vertex in part:
        assert np.isclose(dense, vertex).all(axis=1).any()
    np.testing.assert_allclose(np.diff(dense[:5, 2]), 2.5)  # z linear along the first segment


def test_predicted_runs_split_at_gaps():
    line = PredictedLine("R1", np.array([1.0, 2.0, np.nan, 4.0, np.nan, 6.0, 7.0, 8.0]), np.arange(8.0))
    assert [run[:, 0].tolist() for run in line.runs()] == [[1.0, 2.0], [6.0, 7.0, 8.0]]


def test_ground_lines_predicted_by_the_true_scene_lie_on_their_true_images(roads):
    """Map lines with 1 m horizontal and 2 m height noise (0.4 px at 2.36 m GSD), densified and
    projected by the true scene, pass within 1.6 px of every true image point of the road and
    within 0.5 px in the median; the onboard model (metres of orbit and attitude error) misses
    them by far more: what the prediction shows the user is where to look, not where it is."""
    result = roads["result"]
    for name, worst, typical in (("true_scene", 1.6, 0.5), ("onboard_scene", None, None)):
        scene = load_scene(result.folder / f"{name}.json")
        predicted = predict_lines(scene, 0, roads["ids"], roads["parts"], Heights("z", "ellipsoid"))
        assert [p.line_id for p in predicted] == roads["ids"]
        for line in predicted:
            true = np.array([[float(p["col_true"]), float(p["row_true"])] for p in roads["points"]
                             if p["line_id"] == line.line_id])
            distance = distances_to_polylines(true, line.runs())
            if worst is None:
                assert np.median(distance) > 5.0, (line.line_id, np.median(distance))
            else:
                assert distance.max() < worst and np.median(distance) < typical, (line.line_id, distance)


def test_prediction_with_a_constant_height_far_from_the_terrain_moves_the_lines(roads):
    scene = load_scene(roads["result"].true_scene)
    flat = [p[:, :2] for p in roads["parts"]]
    high = predict_lines(scene, 0, roads["ids"], flat, Heights("constant", "ellipsoid", value=3000.0))
    on_z = predict_lines(scene, 0, roads["ids"], roads["parts"], Heights("z", "ellipsoid"))
    shift = np.hypot(high[0].col - on_z[0].col, high[0].row - on_z[0].row)
    assert np.nanmin(shift) > 1.0  # an off-nadir view sees height as displacement
    with pytest.raises(InputError, match="no Z values"):
        predict_lines(scene, 0, roads["ids"], flat, Heights("z", "ellipsoid"))


def test_saved_lines_read_back(tmp_path):
    from pushbroom_adjust.core.observations.lines import write_gpkg
    editor = LineEditor()
    for col, row in ((10.25, 20.5), (30.0, 40.0), (60.0, 45.0)):
        editor.add_vertex(col, row)
    editor.finish()
    editor.pair_selected("R7")
    write_gpkg(tmp_path / "lines.gpkg", image=editor.image_lines("HRC", 0.7))
    back = read_image_lines(tmp_path / "lines.gpkg")
    assert back.line_id.tolist() == ["R7"] and back.camera.tolist() == ["HRC"]
    np.testing.assert_allclose(np.c_[back.col, back.row], [[10.25, 20.5], [30, 40], [60, 45]])
    np.testing.assert_allclose(back.sigma_px, 0.7)
    again = LineEditor()
    again.load(back)
    assert again.lines[0].vertices == editor.lines[0].vertices and again.lines[0].line_id == "R7"


def test_editor_snaps_the_selected_line_undoably_and_saves_its_sigmas():
    """A line clicked 2 px beside a bright 3 px band: snapped onto it with per-vertex sigmas,
    Undo restores the clicks, the sigmas reach the saved ImageLines."""
    from pushbroom_adjust.core.measure.snapping import SnapSettings
    image = np.full((200, 200), 60.0) + np.random.default_rng(0).normal(0, 3, (200, 200))
    image[:, 99:102] = 200.0                 # the band's centre: col 100.5
    editor = LineEditor()
    clicks = [(102.5, 30.0), (98.0, 80.0), (103.0, 130.0), (101.5, 170.0)]
    for col, row in clicks:
        editor.add_vertex(col, row)
    editor.finish()
    refined, total = editor.snap_selected(image, SnapSettings())
    line = editor.lines[0]
    assert (refined, total) == (4, 4)
    np.testing.assert_allclose([c for c, _ in line.vertices], 100.5, atol=0.1)
    assert all(0.1 <= s < 0.5 for s in line.sigmas)
    assert editor.undo() == "snap" and line.vertices == clicks and line.sigmas is None
    editor.snap_selected(image, SnapSettings())
    editor.pair_selected("R1")
    np.testing.assert_allclose(editor.image_lines("HRC").sigma_px, line.sigmas)
    assert editor.undo() == "snap" and editor.undo() == "line" and editor.lines == []
