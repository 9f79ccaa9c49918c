"""pushbroom:importgcps in real QGIS: a simulated scene's gcps.csv, a georeferencer .points file
and a point layer in UTM, each written as a GeoPackage the core reads back; the style flags
outside points and large residuals."""
import importlib

import numpy as np
import pytest
from pyproj import Transformer
from qgis.core import (QgsExpressionContextUtils, QgsFeature, QgsField, QgsGeometry, QgsPointXY,
                       QgsProcessingException, QgsRenderContext, QgsVectorLayer)
from qgis.PyQt.QtCore import QVariant

from tests.support.csvrows import read_rows, write_rows
from tests.support.paths import PLUGIN
from tests.support.processing import RecordingFeedback

FIELDS = ["id", "role", "camera", "col", "row", "h", "sigma_px", "sigma_xy", "sigma_z", "res_col", "res_row",
          "res_px", "res_m", "inside"]


@pytest.fixture(scope="module")
def core(plugin):
    """The plugin's core modules, imported the way QGIS imports the plugin."""
    return {name: importlib.import_module(f"{PLUGIN}.core.{path}") for name, path in
            (("gcps", "observations.gcps"), ("formats", "formats"), ("scene_json", "formats.scene_json"),
             ("geodesy", "geodesy"))}


def _run(params, feedback=None):
    import processing
    return processing.run("pushbroom:importgcps", params, feedback=feedback)


@pytest.mark.parametrize("fields", [{"ROLE_FIELD": "role", "CAMERA_FIELD": "camera"}, {}], ids=["named", "as_it_is"])
def test_import_simulated_gcps_csv(simulated, core, tmp_path, fields):
    """With the role and camera fields named, and without: the columns role and camera are read under
    their own names."""
    rows = read_rows(simulated["GCPS"])
    for r in rows[::4]:  # some check points, so that the roles are read, not assumed
        r["role"] = "check"
    gcps_csv = write_rows(tmp_path / "gcps.csv", rows)
    out = _run({"SCENE": simulated["ONBOARD_SCENE"], "INPUT_FILE": str(gcps_csv), "Z_FIELD": "h",
                **fields, "HEIGHT_SOURCE": "z", "Z_DATUM": "ellipsoid",
                "SIGMA_PX": 0.3, "OUTPUT": str(tmp_path / "gcps.gpkg")})["OUTPUT"]
    layer = QgsVectorLayer(out, "gcps", "ogr")
    assert layer.isValid() and layer.featureCount() == len(rows)
    # after the GeoPackage fid; 'scene': the simulator's column (the member of its strip) read under its name
    assert layer.fields().names()[1:] == FIELDS + ["scene"]
    assert layer.crs().authid() == "EPSG:4979"
    table = core["gcps"].read_gpkg(out)
    by_id = {r["id"]: r for r in rows}
    assert table.scene.tolist() == [by_id[i]["scene"] for i in table.id]
    assert [by_id[i]["role"] for i in table.id] == table.role.tolist() and "check" in table.role
    assert np.allclose(table.col, [float(by_id[i]["col"]) for i in table.id], atol=1e-9)
    assert np.allclose(table.h, [float(by_id[i]["h"]) for i in table.id], atol=1e-6)
    assert (table.sigma_px == 0.3).all() and table.scene_path == simulated["ONBOARD_SCENE"]
    # a-priori residuals: the onboard model's projection minus the measured position
    scene = core["formats"].load_scene(simulated["ONBOARD_SCENE"])
    for cam in np.unique(table.camera):
        sel = table.camera == cam
        col, row = scene.ground_to_image(core["geodesy"].geodetic_to_ecef(
            table.lon[sel], table.lat[sel], table.h[sel]), str(cam))
        ok = table.residuals.inside[sel]
        assert np.allclose(table.residuals.col[sel][ok], (col - table.col[sel])[ok], atol=1e-3)
        assert np.allclose(table.residuals.row[sel][ok], (row - table.row[sel])[ok], atol=1e-3)


def _tiny_scene_json(core, path):
    """A one-camera scene: 1000 x 2000 px, ~12 m pixels, over (0 E, 0 N), flying north."""
    from importlib import import_module
    cam_mod = import_module(f"{PLUGIN}.core.model.camera")
    traj = import_module(f"{PLUGIN}.core.model.trajectory")
    sensor = import_module(f"{PLUGIN}.core.model.sensor")
    t = np.arange(-20.0, 21.0, 5.0)
    pos = np.stack([7.0e6 + 0 * t, 1000.0 + 0 * t, 7000.0 * t], 1)
    att = traj.QuaternionPolynomial(0.0, 1.0, np.array([[0.5 ** 0.5, 0], [0, 0], [-(0.5 ** 0.5), 0], [0, 0]]))
    chip = cam_mod.Chip(col_offset=0, n_pixels=1000, kind="look_angle", ux_poly=[0.0], uy_poly=[-0.01, 2e-5])
    cam = cam_mod.Camera("PAN", 1000, 2000, cam_mod.LineTiming(-1.0, 1e-3), [chip])
    scene = sensor.SceneModel("2020-01-01T00:00:00Z", traj.Platform(traj.Ephemeris(t, pos), att), [cam],
                              info={"height_range": [0.0, 100.0]})
    core["scene_json"].save_scene(scene, path)
    return scene


def test_points_file_with_disabled_and_outside_points(core, provider, tmp_path):
    scene = _tiny_scene_json(core, tmp_path / "scene.json")
    col = np.array([100.5, 500.0, 900.0, 300.0, 1300.0])
    row = np.array([200.0, 1000.0, 1800.0, 1500.0, 10.0])
    lon, lat, _ = core["geodesy"].ecef_to_geodetic(scene.image_to_ground(col, row, 0.0))
    lon[1] += 20 * 12.4 / 111320.0  # a blunder: 20 px east
    lines = ["#CRS: EPSG:4326", "mapX,mapY,sourceX,sourceY,enable,dX,dY,residual"]
    lines += [f"{x!r},{y!r},{c!r},{-r!r},{int(i != 3)},0,0,0" for i, (x, y, c, r) in enumerate(zip(lon, lat, col, row))]
    (tmp_path / "img.points").write_text("\n".join(lines) + "\n")
    log = RecordingFeedback()
    out = _run({"SCENE": str(tmp_path / "scene.json"), "INPUT_FILE": str(tmp_path / "img.points"),
                "HEIGHT_SOURCE": "constant", "HEIGHT": 0.0, "OUTPUT": str(tmp_path / "pts.gpkg")}, log)["OUTPUT"]
    text = "\n".join(log.lines)
    assert "1 disabled point(s) imported as check points: 3" in text
    assert "5 points: 4 control, 1 check, 1 outside the image" in text
    assert "median 0.00 px (0.00 m), max 19.9" in text and "kept with inside = 0: 4" in text
    table = core["gcps"].read_gpkg(out)
    assert table.id.tolist() == ["0", "1", "2", "3", "4"]
    assert table.role.tolist() == ["control", "control", "control", "check", "control"]
    assert np.allclose(table.row, row) and np.allclose(table.col, col)
    assert table.residuals.inside.tolist() == [True, True, True, True, False]
    assert table.residuals.px[[0, 2, 3]].max() < 1e-3
    assert table.residuals.px[1] == pytest.approx(20.0, rel=0.01)
    assert table.residuals.m[1] == pytest.approx(20 * 12.4, rel=0.01)

    layer = QgsVectorLayer(out, "gcps", "ogr")
    styles = importlib.import_module(f"{PLUGIN}.ui.outputs").STYLES
    _, ok = layer.loadNamedStyle(str(styles / "gcps.qml"))
    assert ok
    ctx = QgsRenderContext()
    ctx.expressionContext().appendScopes(QgsExpressionContextUtils.globalProjectLayerScopes(layer))
    renderer = layer.renderer().clone()
    renderer.startRender(ctx, layer.fields())
    labels = {}
    for f in layer.getFeatures():
        ctx.expressionContext().setFeature(f)
        labels[f["id"]] = {r.label() for r in renderer.rootRule().children() if r.isFilterOK(f, ctx)}
    renderer.stopRender(ctx)
    assert labels["1"] == {"Control point", "Large a-priori residual (> 3 x median, > 1 px)"}
    assert labels["3"] == {"Check point"}
    assert labels["4"] == {"Control point", "Outside the image"}


def test_point_layer_in_utm_and_input_errors(core, provider, tmp_path):
    scene = _tiny_scene_json(core, tmp_path / "scene.json")
    col, row = np.array([10.5, 600.0, 990.0]), np.array([5.0, 700.0, 1990.0])
    lon, lat, _ = core["geodesy"].ecef_to_geodetic(scene.image_to_ground(col, row, 30.0))
    x, y = Transformer.from_crs("EPSG:4326", "EPSG:32631", always_xy=True).transform(lon, lat)
    layer = QgsVectorLayer("Point?crs=EPSG:32631", "gcp", "memory")
    layer.dataProvider().addAttributes([QgsField("name", QVariant.String), QgsField("c", QVariant.Double),
                                        QgsField("r", QVariant.Double)])
    layer.updateFields()
    feats = []
    for i in range(3):
        f = QgsFeature(layer.fields())
        f.setGeometry(QgsGeometry.fromPointXY(QgsPointXY(x[i], y[i])))
        f.setAttributes([f"p{i}", float(col[i]), float(row[i])])
        feats.append(f)
    layer.dataProvider().addFeatures(feats)
    params = {"SCENE": str(tmp_path / "scene.json"), "INPUT": layer, "ID_FIELD": "name", "COL_FIELD": "c",
              "ROW_FIELD": "r", "HEIGHT_SOURCE": "constant", "HEIGHT": 30.0, "OUTPUT": str(tmp_path / "layer.gpkg")}
    table = core["gcps"].read_gpkg(_run(params)["OUTPUT"])
    assert table.id.tolist() == ["p0", "p1", "p2"]
    assert np.allclose(table.lon, lon, atol=1e-9) and np.allclose(table.lat, lat, atol=1e-9)
    assert table.residuals.px.max() < 1e-3 and table.residuals.inside.all()
    temporary = _run({**params, "OUTPUT": "TEMPORARY_OUTPUT"})["OUTPUT"]
    assert temporary.endswith(".gpkg") and len(core["gcps"].read_gpkg(temporary)) == 3
    with pytest.raises(QgsProcessingException, match="Z values"):
        _run({**params, "HEIGHT_SOURCE": "z", "Z_DATUM": "ellipsoid"})  # a 2D layer has no Z
    with pytest.raises(QgsProcessingException, match="either INPUT_FILE .* or INPUT .*not both"):
        _run({**params, "INPUT_FILE": str(tmp_path / "scene.json")})
    with pytest.raises(QgsProcessingException, match="no field 'rr'"):
        _run({**params, "ROW_FIELD": "rr"})
    with pytest.raises(QgsProcessingException, match="GeoPackage"):
        _run({**params, "OUTPUT": str(tmp_path / "layer.shp")})



def test_the_simulators_three_camera_gcps_import_as_they_are_on_the_command_line(three_line, qgis_process, core,
                                                                                  tmp_path):
    """No ID_FIELD, ROLE_FIELD nor CAMERA_FIELD: the columns id, role and camera of the simulator's gcps.csv
    (three cameras: without the camera column it would be refused) are read under their own names."""
    rows = read_rows(three_line["GCPS"])
    out = tmp_path / "gcps.gpkg"
    done = qgis_process("run", "pushbroom:importgcps", "--", f"SCENE={three_line['ONBOARD_SCENE']}",
                        f"INPUT_FILE={three_line['GCPS']}", "Z_FIELD=h", "Z_DATUM=ellipsoid", f"OUTPUT={out}")
    assert done.returncode == 0, done.stdout + done.stderr
    table = core["gcps"].read_gpkg(out)
    expected = {(r["id"], r["camera"]): r["role"] for r in rows}
    assert {(i, c): r for i, c, r in zip(table.id, table.camera, table.role)} == expected
    assert len(set(table.camera)) == 3


def test_ids_from_line_numbers_and_the_plugins_own_layer_as_it_is(simulated, core, tmp_path):
    """A CSV without an id column: the data line numbers are the ids (ID_FIELD empty, its default). The
    layer importgcps wrote, imported again without field parameters: ids, roles and cameras kept."""
    rows = read_rows(simulated["GCPS"])
    for r in rows[::3]:
        r["role"] = "check"
    no_ids = write_rows(tmp_path / "no_ids.csv", rows, [k for k in rows[0] if k != "id"])
    common = {"SCENE": simulated["ONBOARD_SCENE"], "HEIGHT_SOURCE": "z", "Z_DATUM": "ellipsoid"}
    first = _run({**common, "INPUT_FILE": str(no_ids), "Z_FIELD": "h", "OUTPUT": str(tmp_path / "a.gpkg")})["OUTPUT"]
    table = core["gcps"].read_gpkg(first)
    assert table.id.tolist() == [str(i) for i in range(1, len(rows) + 1)]
    assert table.role.tolist() == [r["role"] for r in rows] and "check" in table.role
    again = core["gcps"].read_gpkg(_run({**common, "INPUT": first, "OUTPUT": str(tmp_path / "b.gpkg")})["OUTPUT"])
    assert again.id.tolist() == table.id.tolist() and again.role.tolist() == table.role.tolist()
    assert again.camera.tolist() == table.camera.tolist()
    assert np.allclose(again.h, table.h, atol=1e-6) and np.allclose(again.col, table.col, atol=1e-9)
