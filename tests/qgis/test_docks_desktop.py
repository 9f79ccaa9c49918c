"""Both docks in the real QGIS desktop (issue 30), from start-up to closing them, as a new user with
only an orthoimage loaded (no DEM): QGIS started under a virtual display with a fresh profile and the
plugin enabled (tests/support/desktop.py), driven by tests/support/desktop_docks.py.

Asserted: no CRITICAL message in the message log from start-up on (no red bar either), no
'Duplicate output' at provider load, no Python exception or warning of the plugin, nothing on
stderr; the DEM boxes start empty and do not offer the orthoimage; a GCP measured by clicks is
saved with the constant height (the EGM96 geoid at the point, constant 0 m) and the message and
the table say so; a DEM that does not cover the point is named and no ground is given (nothing
saved); Delete and Ctrl+Z act on the GCP dock; the docks open a scene file and its raw image, make
their display copies in the profile's cache, and leave the scenes' folders untouched; the docks
are tabs of one area and reachable from the Processing menu and toolbox."""
import numpy as np
from osgeo import gdal, osr

from tests.support.desktop import run_desktop
from tests.support.gcpblock import NAMES, gcp_block, true_ground, true_pixel  # noqa: F401 (the fixture)
from tests.support.hostile import assert_unchanged, snapshot
from tests.support.paths import REPO


def far_dem(path, lon: float, lat: float) -> str:
    """A float DEM of 0.01 deg a side, one degree east of (lon, lat): it does not cover the block."""
    ds = gdal.GetDriverByName("GTiff").Create(str(path), 20, 20, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((lon + 1.0, 0.0005, 0.0, lat + 0.005, 0.0, -0.0005))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).Fill(500.0)
    ds = None
    return str(path)


def test_both_docks_in_the_qgis_desktop(plugin, gcp_block, tmp_path):  # noqa: F811
    from pushbroom_adjust.core.dem import to_ellipsoidal
    result = gcp_block["result"]
    point_id, other = gcp_block["inside"][:2]
    lon, lat, _ = true_ground(gcp_block, point_id)
    members = [result.members[name] for name in NAMES]
    watched = [m["onboard_scene"].parent for m in members]
    before = snapshot(*watched)
    (tmp_path / "far").mkdir()
    seen, stderr = run_desktop(REPO / "tests" / "support" / "desktop_docks.py", {
        "names": list(NAMES), "scenes": [str(m["onboard_scene"]) for m in members],
        "reference": str(result.reference), "far_dem": far_dem(tmp_path / "far" / "dem.tif", lon, lat),
        "point": {"lon": lon, "lat": lat, "pixels": {n: true_pixel(gcp_block, point_id, n).tolist() for n in NAMES}},
        "ground_line": [true_ground(gcp_block, i)[:2] for i in (point_id, other)],
        "gcps": str(tmp_path / "gcps.gpkg"), "gcps_far": str(tmp_path / "far.gpkg"),
        "project": str(tmp_path / "project.qgs")}, tmp_path / "desktop")
    print(seen.get("gcp"), seen.get("far"), seen.get("lines"), sep="\n")

    # nothing alarming from start-up to the docks closed and the plugin unloaded
    assert seen["exceptions"] == []
    assert "pushbroom" in seen["startup"].lower() or seen["entry_points"]  # the plugin loaded
    assert "CRITICAL" not in seen["startup"], seen["startup"]
    assert "Duplicate output" not in seen["startup"]
    assert [m for m in seen["log"] if m[0] >= 2] == [], seen["log"]
    assert [m for m in seen["log"] if "pushbroom" in m[2].lower()] == [], seen["log"]
    assert seen["bar"] == []
    assert stderr.strip() == "", stderr

    # the DEM boxes start empty and leave the orthoimage out
    assert seen["gcp_dem"] == {"current": False, "offered": []}
    assert [ok for ok, _ in seen["added"]] == [True, True], seen["added"]
    # measured without a DEM: the constant height (0 m above the geoid), said in the message and the table
    h = float(to_ellipsoidal(np.array([lon]), np.array([lat]), np.array([0.0]), "geoid")[0])
    gcp = seen["gcp"]
    assert abs(gcp["h"] - h) < 0.01 and gcp["saved"] and np.allclose(gcp["saved_h"], h, atol=0.01)
    assert "from the constant 0.0 m (geoid), no DEM chosen" in gcp["message"], gcp["message"]
    assert "the constant 0.0 m (geoid), no DEM chosen" in gcp["table"], gcp["table"]
    # a DEM that does not cover the point: named, no ground, nothing saved
    far = seen["far"]
    assert "far/dem.tif gives no height for 1 of 1 points (1 off its extent): point(s) G2" in far["message"], \
        far["message"]
    assert far["offered"] == ["far dem"] and not far["ground"] and not far["saved"]
    assert "G2 have no ground position" in far["save_message"]
    assert far["after_delete"] == ["G1"] and far["after_undo"] == ["G1", "G2"], far
    assert far["undo_message"] == "Undone: delete point"
    # the lines dock: a tab beside the GCP dock, no DEM offered, the prediction on the constant, said
    assert seen["tabified"]
    lines = seen["lines"]
    assert lines["opened"] and lines["offered"] == ["far dem"] and not lines["dem"] and lines["lines"] == 1
    assert "1 of 1 ground lines predicted" in lines["message"] and "no DEM chosen" in lines["message"], lines
    assert seen["after_project_read"] is False  # the dock's canvas keeps no CRS: nothing to transform
    # entry points besides the toolbar, distinct icons
    assert seen["entry_points"] == {"processing_menu": ["Measure GCPs on the raw images",
                                                        "Digitise control lines on the raw image"],
                                    "toolbox": ["Measure GCPs on the raw images",
                                                "Digitise control lines on the raw image"],
                                    "icons_differ": True}
    # display copies in the profile's cache, none beside the scenes; the scenes' folders untouched
    cache = tmp_path / "desktop" / "profiles" / "default" / "cache" / "pushbroom_adjust" / "display"
    cached = sorted(cache.glob("*.vrt"))
    assert len(cached) == 2, cached
    assert_unchanged(before, watched)
