"""Tie points: readers, checks against a simulated TH-1 three-line scene, GeoPackage round trip."""
import csv
import logging

import numpy as np
import pytest

from pushbroom_adjust.core.observations import tiepoints as tp
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.presets import CAMERA_ERRORS
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate


@pytest.fixture(scope="module")
def th1(tmp_path_factory):
    """A TH-1 block with the preset's trajectory and installation errors but no camera (interior)
    errors: these tests are about reading and checking tie points, and the a-priori check flags a
    point against the cameras' common error. With the preset's interior errors (principal point
    10 px, decentring 7-8 px, different per camera) the onboard residuals are 9.7 px rms, not
    3.3, and a 40 px mismatch is no longer outstanding (its point's residual 19 px vs 28 px)."""
    folder = tmp_path_factory.mktemp("th1")
    res = simulate("th1_tlc", folder, seed=3, n_gcps=10, errors=dict.fromkeys(CAMERA_ERRORS, 0.0),
                   gcp_settings=GcpSettings(n_gcps=10, image_noise=0.3, n_tie_points=60))
    with open(res.tie_points) as f:
        rows = list(csv.DictReader(f))
    return {"csv": res.tie_points, "rows": rows, "true": load_scene(res.true_scene),
            "onboard": load_scene(res.onboard_scene), "onboard_path": str(res.onboard_scene)}


def _write(path, text):
    path.write_text(text)
    return path


def _table(th1, **changes):
    t = tp.read_csv(th1["csv"])
    return tp.TieTable(*(changes.get(k, getattr(t, k)) for k in tp.TieTable.ARRAYS))


def test_the_simulators_csv_reads_as_it_is(th1):
    t = tp.read_csv(th1["csv"])
    rows = th1["rows"]
    assert len(t) == len(rows) == 177
    assert t.id.tolist() == [r["id"] for r in rows] and t.camera.tolist() == [r["camera"] for r in rows]
    assert np.array_equal(t.col, [float(r["col"]) for r in rows])
    # the column 'scene' (the member of the simulated strip, one scene here) is read under its name
    assert (t.sigma_px == tp.DEFAULT_SIGMA_PX).all() and (t.scene == "1").all()
    assert t.points()[0].size == 60


def test_semicolons_decimal_commas_scene_and_sigma_columns(tmp_path):
    path = _write(tmp_path / "t.csv", "pt;cam;x;y;img;s\nA;FWD;10,5;20,25;S1;0,8\nA;BWD;11;21;S1;\nB;NAD;5;6;S2;2\n")
    t = tp.read_csv(path, tp.CsvMapping(id="pt", camera="cam", col="x", row="y", scene="img", sigma_px="s"), 0.4)
    assert t.col.tolist() == [10.5, 11.0, 5.0] and t.row.tolist() == [20.25, 21.0, 6.0]
    assert t.sigma_px.tolist() == [0.8, 0.4, 2.0] and t.scene.tolist() == ["S1", "S1", "S2"]


@pytest.mark.parametrize("text, expected", [
    ("id,camera,col,row\nA,NAD,x1,3\n", "column 'col' is not a number for point(s) A"),
    ("id,camera,col,row\nA,NAD,,3\n", "col is missing or not a number for point(s) A"),
    ("id,camera,col\nA,NAD,1\n", "no column 'row' (columns: id, camera, col)"),
    ("id,camera,col,row\n", "needs a header line and at least one point"),
    ("id,camera,col,row\n,NAD,1,2\n", "empty point id in data line(s) 1"),
    ("id,camera,col,row\nA,NAD,1e12,2\n", "beyond any image"),
    ("id,camera,col,row,s\nA,NAD,1,2,-1\n", "per-point sigma field 's' must hold numbers > 0"),
])
def test_bad_csv_is_refused_naming_what(tmp_path, text, expected):
    path = _write(tmp_path / "bad.csv", text)
    with pytest.raises(InputError, match="bad.csv") as info:
        tp.read_csv(path, tp.CsvMapping(sigma_px="s" if ",s" in text else None))
    assert expected in str(info.value)


def test_true_model_intersects_the_true_points_to_a_centimetre(th1):
    t = tp.read_csv(th1["csv"], tp.CsvMapping(col="col_true", row="row_true"))
    t = tp.check_against_scene(t, th1["true"], "true.json")
    truth = geodetic_to_ecef(*(np.array([float(r[k]) for r in th1["rows"]]) for k in ("lon_true", "lat_true", "h_true")))
    found = geodetic_to_ecef(t.apriori.lon, t.apriori.lat, t.apriori.h)
    assert np.linalg.norm(found - truth, axis=1).max() < 0.01  # m
    assert np.nanmax(t.apriori.res_px) < 1e-3                  # px
    assert t.scene_path == "true.json" and tp.suspect_points(t).size == 0


def test_onboard_apriori_residuals_and_summary(th1):
    t = tp.check_against_scene(tp.read_csv(th1["csv"]), th1["onboard"], th1["onboard_path"])
    s = tp.summary(t)
    # the onboard model's errors are mostly common to the three cameras: a few px per point
    # (measured: 177 observations, 3.31 px rms, median a-priori ground error 85.5 m)
    assert s["points"] == 60 and s["observations"] == 177 and s["single"] == 0
    assert s["cameras_per_point"] == {2: 3, 3: 57} and s["cameras"] == {"BWD": 59, "FWD": 58, "NAD": 60}
    assert 2.0 < s["rms_px"] < 8.0 and s["suspect"] == 0
    truth = geodetic_to_ecef(*(np.array([float(r[k]) for r in th1["rows"]]) for k in ("lon_true", "lat_true", "h_true")))
    error = np.linalg.norm(geodetic_to_ecef(t.apriori.lon, t.apriori.lat, t.apriori.h) - truth, axis=1)
    assert 1.0 < np.median(error) < 500.0  # m: the onboard trajectory error, not the intersection


def test_a_mismatched_point_is_named(th1, caplog):
    t = tp.read_csv(th1["csv"])
    col = t.col.copy()
    col[np.nonzero(t.id == "T7")[0][0]] += 40.0
    with caplog.at_level(logging.WARNING, logger="pushbroom_adjust.core.observations.tiepoints"):
        checked = tp.check_against_scene(_table(th1, col=col), th1["onboard"])
    assert tp.suspect_points(checked).tolist() == ["T7"]
    assert "likely mismatched points, check them: T7" in caplog.text


def test_a_point_in_one_camera_is_kept_with_a_warning(th1, caplog, tmp_path):
    t = tp.read_csv(th1["csv"])
    keep = ~((t.id == "T5") & (t.camera != "NAD"))
    with caplog.at_level(logging.WARNING, logger="pushbroom_adjust.core.observations.tiepoints"):
        checked = tp.check_against_scene(t.select(keep), th1["onboard"])
    assert "1 tie point(s) seen in one camera only" in caplog.text and ": T5" in caplog.text
    one = checked.id == "T5"
    assert checked.apriori.rays[one].tolist() == [1.0] and np.isnan(checked.apriori.lon[one]).all()
    assert tp.summary(checked)["single"] == 1
    tp.write_gpkg(checked, tmp_path / "t.gpkg")
    back = tp.read_gpkg(tmp_path / "t.gpkg")
    assert np.isnan(back.apriori.h[back.id == "T5"]).all() and np.isfinite(back.apriori.h[back.id != "T5"]).all()


def test_geopackage_round_trip(th1, tmp_path):
    t = tp.read_csv(th1["csv"])
    t = tp.check_against_scene(_table(th1, sigma_px=np.linspace(0.2, 2.0, len(t)), scene=np.where(t.row > 5000, "S2", "S1")),
                               th1["onboard"], th1["onboard_path"])
    tp.write_gpkg(t, tmp_path / "t.gpkg")
    back = tp.read_gpkg(tmp_path / "t.gpkg")
    for name in tp.TieTable.ARRAYS:
        assert np.array_equal(getattr(back, name), getattr(t, name)), name
    for name in tp.Apriori.FIELDS:
        assert np.allclose(getattr(back.apriori, name), getattr(t.apriori, name), rtol=0, atol=1e-9), name
    assert back.scene_path == th1["onboard_path"]


@pytest.mark.parametrize("change, expected", [
    (lambda t: {"camera": np.where(t.camera == "FWD", "FORWARD", t.camera)},
     "camera 'FORWARD' of point(s) T1"),
    (lambda t: {"id": np.where(t.id == "T2", "T3", t.id)}, "point id(s) T3 occur more than once for the same camera"),
    (lambda t: {"col": np.where(t.id == "T4", -3.0, t.col)}, "point(s) T4 lie outside their camera's image"),
    (lambda t: {"col": 100 + t.col / 20, "row": 100 + t.row / 20}, "cover only 5% x 5% of the image (one corner)"),
])
def test_against_the_scene_bad_tables_are_refused(th1, change, expected):
    t = tp.read_csv(th1["csv"])
    with pytest.raises(InputError) as info:
        tp.check_against_scene(_table(th1, **change(t)), th1["onboard"])
    assert expected in str(info.value)
    if "FORWARD" in expected:
        assert "(cameras: NAD, FWD, BWD)" in str(info.value)


def test_an_empty_table_is_refused(th1):
    with pytest.raises(InputError, match="no tie points"):
        tp.check_against_scene(tp.TieTable([], [], [], [], 0.5, ""), th1["onboard"])
    with pytest.raises(InputError, match="no tie points"):
        tp.build_table([], [], [], [])


def test_a_block_whose_scenes_share_a_camera_name_is_summed_up_by_scene(tmp_path):
    """Every scene of a block may call its camera 'NAD': by_scene keys the cameras by '<scene>/<camera>';
    the layer keeps each observation's scene without an a-priori intersection."""
    t = tp.build_table(["T1", "T1", "T1", "T2", "T2"], ["NAD"] * 5, [10.0, 12, 11, 20, 21], [5.0, 6, 7, 8, 9],
                       scene=["a", "b", "c", "a", "b"])
    assert tp.summary(t)["cameras"] == {"NAD": 5}
    s = tp.summary(t, by_scene=True)
    assert s["cameras"] == {"a/NAD": 2, "b/NAD": 2, "c/NAD": 1} and s["cameras_per_point"] == {2: 1, 3: 1}
    assert s["pairs"] == {"a/NAD-b/NAD": 2, "a/NAD-c/NAD": 1, "b/NAD-c/NAD": 1} and s["single"] == 0
    tp.write_gpkg(t, tmp_path / "t.gpkg")
    back = tp.read_gpkg(tmp_path / "t.gpkg")
    assert back.scene.tolist() == ["a", "b", "c", "a", "b"] and back.apriori is None
