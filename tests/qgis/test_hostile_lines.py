"""Hostile input to pushbroom:importlines and bundleadjust LINES (control lines, Tommaselli &
Marcato Junior 2012): each case one bad line input, refused with a message naming the parameter
and the lines at fault while the inputs and the output folder stay unchanged, or (lines all
running one way) adjusted with a warning naming the free direction."""
from __future__ import annotations

import shutil

import numpy as np
import pytest
from osgeo import ogr, osr

from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback


@pytest.fixture(scope="module")
def lines_sim(provider, tmp_path_factory):
    from pushbroom_adjust.simulation.roads import RoadSettings
    from pushbroom_adjust.simulation.measurements import GcpSettings
    from pushbroom_adjust.simulation.simulator import simulate
    folder = tmp_path_factory.mktemp("hostile_lines")
    result = simulate("cbers02b_hrc", folder / "sim", seed=4, errors=dict(ccd_shift=0.0, ccd_rotation=0.0),
                      gcp_settings=GcpSettings(n_gcps=30, check_fraction=0.3, image_noise=0.5),
                      road_settings=RoadSettings(n_lines=6))
    import processing
    gcps = folder / "gcps.gpkg"
    processing.run("pushbroom:importgcps", {"SCENE": str(result.onboard_scene), "INPUT_FILE": str(result.gcps),
                                            "ROLE_FIELD": "role", "Z_FIELD": "h", "HEIGHT_SOURCE": "z",
                                            "Z_DATUM": "ellipsoid", "OUTPUT": str(gcps)})
    good = folder / "control_lines.gpkg"
    processing.run("pushbroom:importlines", _params(result, good))
    return {"result": result, "gcps": gcps, "lines": good}


def _params(result, out, ground=None, image=None, **extra):
    return {"SCENE": str(result.onboard_scene), "INPUT": ground or f"{result.lines}|layername=ground_lines",
            "IMAGE_LINES": image or f"{result.lines}|layername=image_lines", "HEIGHT_SOURCE": "z",
            "Z_DATUM": "ellipsoid", "OUTPUT": str(out), **extra}


def _read(path, layer):
    """[(fields dict, [(x, y[, z][, m])...])] of a line layer."""
    ds = ogr.Open(str(path))
    lyr = ds.GetLayer(layer)
    out = []
    for f in lyr:
        g = f.GetGeometryRef()
        pts = [g.GetPoint(i) + ((g.GetM(i),) if g.IsMeasured() else ()) for i in range(g.GetPointCount())]
        out.append(({k: f.GetField(k) for k in f.keys()}, pts))
    return out, lyr.GetSpatialRef(), lyr.GetGeomType()


def _write(path, layer, features, srs, geom_type):
    """A GeoPackage layer (a shapefile for a .shp path) of line features [(fields, points)]
    (srs None: no CRS)."""
    driver = "ESRI Shapefile" if path.suffix == ".shp" else "GPKG"
    ds = ogr.GetDriverByName(driver).CreateDataSource(str(path)) if not path.exists() else ogr.Open(str(path), 1)
    lyr = ds.CreateLayer(layer, srs, geom_type)
    for name, value in features[0][0].items():
        kind = ogr.OFTReal if isinstance(value, float) else ogr.OFTString
        lyr.CreateField(ogr.FieldDefn(name, kind))
    for fields, pts in features:
        f = ogr.Feature(lyr.GetLayerDefn())
        for k, v in fields.items():
            f.SetField(k, v)
        g = ogr.Geometry(geom_type)
        for p in pts:
            if ogr.GT_HasM(geom_type):
                g.AddPointM(p[0], p[1], p[-1])
            elif ogr.GT_HasZ(geom_type):
                g.AddPoint(p[0], p[1], p[2])
            else:
                g.AddPoint_2D(p[0], p[1])
        f.SetGeometry(g)
        lyr.CreateFeature(f)
    ds = None
    return str(path) if path.suffix == ".shp" else f"{path}|layername={layer}"


def _ground(sim, tmp_path, edit, srs="keep", flat=False):
    """The simulated ground lines edited; without CRS as a shapefile without .prj (a GeoPackage
    layer always has one: srs_id 0 is 'undefined geographic')."""
    feats, ref, kind = _read(sim["result"].lines, "ground_lines")
    feats = edit(feats)
    if srs is None:  # shapefile field names have at most 10 characters
        feats = [({"line_id": fields["line_id"]}, pts) for fields, pts in feats]
    path = tmp_path / ("ground.shp" if srs is None else "ground.gpkg")
    return _write(path, "ground_lines", feats, ref if srs == "keep" else srs, ogr.wkbLineString if flat else kind)


def _image(sim, tmp_path, edit):
    feats, ref, kind = _read(sim["result"].lines, "image_lines")
    return _write(tmp_path / "image.gpkg", "image_lines", edit(feats), ref, kind)


def _shift(pts, dlon):
    return [(p[0] + dlon,) + tuple(p[1:]) for p in pts]


GROUND_CASES = {
    "a line layer without CRS": (lambda f: f, dict(srs=None), ["INPUT", "no CRS"]),
    "a zero-length line": (lambda f: [(f[0][0], [f[0][1][0]] * 3)] + f[1:], {}, ["INPUT", "zero length", "R1"]),
    "a self-intersecting line": (lambda f: [(f[0][0], [f[0][1][0], f[0][1][-1], (f[0][1][0][0], f[0][1][-1][1], 300.0),
                                                        (f[0][1][-1][0], f[0][1][0][1], 300.0)])] + f[1:], {},
                                 ["INPUT", "intersect themselves", "R1"]),
    "a paired ground line outside the scene": (lambda f: [(f[0][0], _shift(f[0][1], 1.0))] + f[1:], {},
                                               ["outside the scene", "R1"]),
    "a 2D layer with heights from z": (lambda f: f, dict(flat=True), ["INPUT", "no Z values"]),
    "a negative sigma": (lambda f: [({**f[0][0], "sigma_across": -1.0}, f[0][1])] + f[1:], {},
                         ["INPUT", "sigma_across", "R1"]),
}


@pytest.mark.parametrize("case", list(GROUND_CASES))
def test_bad_ground_lines_are_refused(lines_sim, tmp_path, case):
    edit, how, texts = GROUND_CASES[case]
    ground = _ground(lines_sim, tmp_path, edit, **how)
    out = tmp_path / "out"
    out.mkdir()
    assert_refused("pushbroom:importlines", _params(lines_sim["result"], out / "cl.gpkg", ground=ground), *texts,
                   watch=[tmp_path / "ground.gpkg", tmp_path / "ground.shp", lines_sim["result"].lines, out])


IMAGE_CASES = {
    "image lines with one vertex": (lambda f: [(f[0][0], f[0][1][:1])] + f[1:], ["IMAGE_LINES", "fewer than two"]),
    "ids that pair nothing": (lambda f: [({**f[0][0], "line_id": "NOPE"}, f[0][1])] + f[1:],
                              ["NOPE", "pair with no ground line"]),
    "image lines outside the image": (lambda f: [(f[0][0], [(p[0] + 20000.0,) + p[1:] for p in f[0][1]])] + f[1:],
                                      ["outside the image"]),
    "a camera the scene lacks": (lambda f: [({**f[0][0], "camera": "PAN"}, f[0][1])] + f[1:], ["PAN", "cameras"]),
    "image lines not in the pixel frame (y > 0)": (lambda f: [(f[0][0], [(p[0], -p[1]) + p[2:] for p in f[0][1]])]
                                                   + f[1:], ["IMAGE_LINES", "y > 0"]),
    "an image line crossing itself": (lambda f: [(f[0][0], [(0.0, -0.0, 0.0, 1.0), (100.0, -100.0, 0.0, 1.0),
                                                            (100.0, -0.0, 0.0, 1.0), (0.0, -100.0, 0.0, 1.0)])]
                                      + f[1:], ["IMAGE_LINES", "intersect themselves"]),
}


@pytest.mark.parametrize("case", list(IMAGE_CASES))
def test_bad_image_lines_are_refused(lines_sim, tmp_path, case):
    edit, texts = IMAGE_CASES[case]
    image = _image(lines_sim, tmp_path, edit)
    out = tmp_path / "out"
    out.mkdir()
    assert_refused("pushbroom:importlines", _params(lines_sim["result"], out / "cl.gpkg", image=image), *texts,
                   watch=[tmp_path / "image.gpkg", lines_sim["result"].lines, out])


def test_output_equal_to_the_input_is_refused(lines_sim, tmp_path):
    copy = tmp_path / "lines.gpkg"
    shutil.copy(lines_sim["result"].lines, copy)
    assert_refused("pushbroom:importlines", _params(lines_sim["result"], copy, ground=f"{copy}|layername=ground_lines",
                                                    image=f"{copy}|layername=image_lines"),
                   "OUTPUT", watch=[copy])


def test_a_point_layer_as_input_is_refused(lines_sim, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    assert_refused("pushbroom:importlines", _params(lines_sim["result"], out / "cl.gpkg", ground=str(lines_sim["gcps"])),
                   "INPUT", watch=[lines_sim["gcps"], out])


def test_the_same_layer_twice_is_refused(lines_sim, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    ground = f"{lines_sim['result'].lines}|layername=ground_lines"
    assert_refused("pushbroom:importlines", _params(lines_sim["result"], out / "cl.gpkg", image=ground),
                   "IMAGE_LINES", "same layer", watch=[lines_sim["result"].lines, out])


def test_an_output_that_is_no_geopackage_is_refused(lines_sim, tmp_path):
    assert_refused("pushbroom:importlines", _params(lines_sim["result"], tmp_path / "cl.shp"), "OUTPUT", ".gpkg",
                   watch=[tmp_path])


def _adjust(sim, tmp_path, **extra):
    return {"SCENE": str(sim["result"].onboard_scene), "GCPS": str(sim["gcps"]), "POSITION_MODEL": "polynomial",
            "POSITION_ORDER": 1, "ATTITUDE_MODEL": "polynomial", "ATTITUDE_ORDER": 2,
            "OUTPUT_SCENE": str(tmp_path / "out" / "adjusted.json"), **extra}


def test_bundleadjust_lines_that_are_no_control_lines_are_refused(lines_sim, tmp_path):
    (tmp_path / "out").mkdir()
    ground = f"{lines_sim['result'].lines}|layername=ground_lines"
    ground_only = tmp_path / "ground_only.gpkg"
    _write(ground_only, "roads", _read(lines_sim["result"].lines, "ground_lines")[0],
           _read(lines_sim["result"].lines, "ground_lines")[1], ogr.wkbLineString25D)
    assert ground
    assert_refused("pushbroom:bundleadjust", _adjust(lines_sim, tmp_path, LINES=str(ground_only)), "LINES",
                   watch=[ground_only, tmp_path / "out"])


def test_bundleadjust_line_residuals_without_lines_are_refused(lines_sim, tmp_path):
    (tmp_path / "out").mkdir()
    assert_refused("pushbroom:bundleadjust", _adjust(lines_sim, tmp_path, OUTPUT_LINE_RESIDUALS=str(
        tmp_path / "out" / "lr.gpkg")), "OUTPUT_LINE_RESIDUALS", "LINES", watch=[tmp_path / "out"])


def test_lines_only_parallel_to_each_other_adjust_with_the_free_direction_named(lines_sim, tmp_path):
    """Legitimate input: lines that all run one way are used, and the report says which
    direction they leave to the points."""
    import processing
    from pushbroom_adjust.core.observations import lines as core_lines
    from pushbroom_adjust.core.formats import load_scene
    from tests.support.control_lines import parallel_lines
    parallel = parallel_lines(load_scene(lines_sim["result"].true_scene))
    path = tmp_path / "parallel.gpkg"
    core_lines.write_gpkg(path, parallel.ground, parallel.image)
    (tmp_path / "out").mkdir()
    feedback = RecordingFeedback()
    done = processing.run("pushbroom:bundleadjust", _adjust(lines_sim, tmp_path, LINES=str(path), POSITION_SIGMA=100.0,
                                                            ATTITUDE_SIGMA=5e-4,
                                                            OUTPUT_REPORT=str(tmp_path / "out" / "r.html")),
                          feedback=feedback)
    import json
    rep = json.loads(open(done["OUTPUT_REPORT_JSON"]).read())
    assert not rep["lines"]["directions"]["determined"]
    assert any("not determined by the lines" in w for w in feedback.warnings), feedback.warnings


def test_a_layer_without_crs_is_refused_from_the_command_line(lines_sim, tmp_path, qgis_process):
    ground = _ground(lines_sim, tmp_path, lambda f: f, srs=None)
    out = tmp_path / "out"
    out.mkdir()
    assert_refused_cli(qgis_process, "pushbroom:importlines", _params(lines_sim["result"], out / "cl.gpkg",
                                                                      ground=ground), "no CRS",
                       watch=[tmp_path / "ground.shp", out])


def test_wgs84_is_what_the_output_says(lines_sim):
    ds = ogr.Open(str(lines_sim["lines"]))
    srs = ds.GetLayer("ground_lines").GetSpatialRef()
    assert srs.GetAuthorityCode(None) == "4979" and isinstance(srs, osr.SpatialReference)
    assert np.isfinite([f.GetField("apriori_rms_m") for f in ds.GetLayer("ground_lines")]).all()
