"""The GCP dock's session without its widgets (core.runs.measuregcps), on the rendered block of two
scenes with known truth (tests/support/gcpblock.py): scenes added by their display copies and named,
points measured at their true pixels with their true ground, the markers the dock draws (predictions
through the true models meeting the truth and sharing a label), Snap back onto the truth, the table's
rows, the nearest reference point, saving checked against every file read, and opening back."""
import re
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.files import OutputError
from pushbroom_adjust.core.measure.gcpmeasure import MeasuredPoint, Observation
from pushbroom_adjust.core.measure.sources import open_image_source
from pushbroom_adjust.core.measure.tiematching import View
from pushbroom_adjust.core.observations.gcps import Residuals, read_gpkg, write_gpkg
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.runs.measuregcps import GcpSession, nearest_reference, point_rows
from tests.support.gcpblock import NAMES, gcp_block, true_ground, true_pixel  # noqa: F401 (the fixture)

ON_Z = Heights("z", "ellipsoid")


def folder_names(paths: list[str]) -> list[str]:
    """The block's scene names as the simulator's folders give them (one folder per scene)."""
    return [Path(p).parent.name for p in paths]


def session_of(block, cache) -> GcpSession:
    session = GcpSession()
    for name in NAMES:
        session.add(block["displays"][name], open_image_source(block["displays"][name], cache), folder_names)
    return session


def measure(session: GcpSession, block, point_id: str, offsets=None) -> None:
    """New point ``point_id`` clicked at its true pixel (+ offsets {scene: (dcol, drow)}) in both
    scenes, its ground the truth (its Z, ellipsoidal)."""
    session.editor.new_point(point_id)
    for k, name in enumerate(NAMES):
        session.current = k
        session.measure(*(true_pixel(block, point_id, name) + (offsets or {}).get(name, 0.0)))
    lon, lat, h = true_ground(block, point_id)
    session.set_ground(lon, lat, h, "reference", ON_Z, "the reference point's Z")


def test_scenes_join_the_block_once_named_by_their_files(gcp_block, tmp_path):  # noqa: F811
    session = session_of(gcp_block, tmp_path)
    assert [v.label for v in session.views] == ["nad/NAD", "fwd/NAD"]
    with pytest.raises(InputError, match="add a scene of the block first"):
        session.view()
    with pytest.raises(InputError, match="^nad/NAD is in the block already$"):
        session.add(gcp_block["displays"]["nad"], open_image_source(gcp_block["displays"]["nad"], tmp_path),
                    folder_names)
    assert len(session.views) == len(session.sources) == 2
    files = session.files_read(None)
    assert files["fwd/NAD (display copy)"][0] == str(session.sources[1][1].display)
    assert files["fwd/NAD (display copy)"][1] == gcp_block["displays"]["fwd"]  # the copy opened, besides the cache's
    assert files["nad/NAD (scene file)"] == [str(gcp_block["result"].members["nad"]["onboard_scene"])]
    assert files["DEM"] == []


def test_measuring_and_the_ground_say_what_they_did(gcp_block, tmp_path):  # noqa: F811
    session = session_of(gcp_block, tmp_path)
    point_id = gcp_block["inside"][0]
    session.current = 0
    col, row = true_pixel(gcp_block, point_id, "nad")
    assert session.measure(col, row) == f"Point G1 measured in nad/NAD at col {col:.2f}, row {row:.2f} px"
    assert session.measure(col + 1, row).startswith("Point G1 moved in nad/NAD")
    with pytest.raises(InputError, match="is outside the image of nad \\(500 x 500 px\\)"):
        session.measure(-3.0, row)
    lon, lat, h = true_ground(gcp_block, point_id)
    said = session.set_ground(lon, lat, h, "reference", ON_Z, "its Z")
    assert said == f"Point G1: ground lon {lon:.6f}, lat {lat:.6f} from the reference, h {h:.1f} m (ellipsoidal) from its Z"
    assert session.editor.current().ground.h == h
    session.edit_sigmas(0.4, 0.8, 0.25)
    table = session.editor.table()
    assert (table.sigma_xy[0], table.sigma_z[0], table.sigma_px[0]) == (0.4, 0.8, 0.25)
    assert session.shown() == ("nad", "NAD") and session.selected_values() == ("G1", "control", 0.4, 0.8, 0.25)
    session.current = 1                                            # not measured in fwd: no image sigma there
    assert session.selected_values()[4] is None
    session.editor.new_point("G9")
    assert session.selected_values() == ("G9", "control", None, None, None)
    assert session.ground_marks() == [("G1", lon, lat, False)]     # the points with a ground, the selected last
    session.editor.select(0)
    assert session.ground_marks() == [("G1", lon, lat, True)]
    session.undo()
    session.rename("P7")
    assert session.editor.ids() == ["P7"] and session.undo() == "Undone: edit"
    assert session.delete() == "Point deleted (Ctrl+Z brings it back)" and session.delete().startswith("Select a point")
    assert session.undo() == "Undone: delete point" and session.editor.ids() == ["G1"]


def test_predictions_through_the_true_models_meet_the_truth_and_share_their_label(gcp_block):  # noqa: F811
    """With the true models and the true DEM, the selected point's estimates in fwd (from its ground,
    from its nad observation) fall within 0.1 px of its true pixel: one marker is labelled with both
    sources, the other not; the measured points follow, the selected one as such."""
    views = [View(n, gcp_block["true"][n], 0, Path(gcp_block["result"].members[n]["images"]["NAD"])) for n in NAMES]
    session = GcpSession(views=views)
    ids = gcp_block["inside"][:2]
    for point_id in ids:
        measure(session, gcp_block, point_id)
    session.editor.select(0)
    session.current = 1
    dem = Heights("dem", "geoid", str(gcp_block["result"].dem))
    markers, problem = session.markers(dem)
    assert problem == "" and session.surface(dem, views[1]) is session.surface(dem, views[1])  # read once
    truth = true_pixel(gcp_block, ids[0], "fwd")
    predicted = [m for m in markers if m[2] in ("ground", "scene")]
    assert [m[2] for m in predicted] == ["ground", "scene"]
    assert max(np.hypot(c - truth[0], r - truth[1]) for c, r, _, _ in predicted) < 0.1
    assert [m[3] for m in predicted] == [f"{ids[0]} (ground, nad)", ""]
    assert [(m[2], m[3]) for m in markers[2:]] == [("selected", ids[0]), ("measured", ids[1])]
    assert session.selected_pixels() == [tuple(true_pixel(gcp_block, ids[0], "fwd"))]
    # a point not measured in the scene shown: the mean of its predictions is where the dock zooms
    session.editor.current().observations = [o for o in session.editor.current().observations if o.scene == "nad"]
    session.markers(Heights("dem", "geoid", gcp_block["result"].dem))
    assert np.hypot(*(np.array(session.selected_pixels()[0]) - truth)) < 0.1
    # a DEM that cannot be had is the problem to show, and the measured points are still drawn
    markers, problem = session.markers(Heights("dem", "geoid", None))
    assert "no DEM was given" in problem and [m[2] for m in markers] == ["measured"]


def test_a_dem_of_heights_no_terrain_has_is_refused_as_the_use_cases_refuse_it(gcp_block, tmp_path):  # noqa: F811
    """The block's DEM with 20 km added (a DEM in the wrong unit, or of another quantity): named, as
    pushbroom:groundtoimage names it (core.runs.base.surface_from), not met by rays in silence."""
    ds = gdal.Translate(str(tmp_path / "high.tif"), str(gcp_block["result"].dem))
    band = ds.GetRasterBand(1)
    band.WriteArray(band.ReadAsArray() + 20000.0)
    ds = None
    views = [View(n, gcp_block["true"][n], 0, Path(gcp_block["result"].members[n]["images"]["NAD"])) for n in NAMES]
    session = GcpSession(views=views, current=1)
    measure(session, gcp_block, gcp_block["inside"][0])
    markers, problem = session.markers(Heights("dem", "geoid", str(tmp_path / "high.tif")))
    assert problem.startswith("DEM: ") and "high.tif" in problem, problem
    assert [m[2] for m in markers] == ["selected"]
    with pytest.raises(InputError, match="high.tif"):
        session.snap(Heights("dem", "geoid", str(tmp_path / "high.tif")), False)


def test_snap_to_the_other_scene_puts_the_click_back_on_the_truth(gcp_block, tmp_path):  # noqa: F811
    """A click 2.5 px off in fwd snapped to the nad observation through the onboard models: within
    0.05 px of the truth; the refusals name what is missing."""
    session = session_of(gcp_block, tmp_path)
    point_id = gcp_block["inside"][0]
    measure(session, gcp_block, point_id, {"fwd": np.array([2.0, -1.5])})
    said = session.snap(Heights("dem", "geoid", gcp_block["result"].dem), False)
    assert said.startswith("Snapped by") and " px to nad/NAD (sigma " in said, said
    seen = session.editor.current().observation("fwd", "NAD")
    assert np.hypot(*(np.array([seen.col, seen.row]) - true_pixel(gcp_block, point_id, "fwd"))) < 0.05
    with pytest.raises(InputError, match="^choose the reference orthoimage layer to snap to$"):
        session.snap(ON_Z, True)
    session.editor.delete_observation("nad", "NAD")
    with pytest.raises(InputError, match=f"^point {point_id} is measured in no other scene"):
        session.snap(ON_Z, False)


def test_saved_never_over_a_file_read_then_opened_back_with_residuals(gcp_block, tmp_path):  # noqa: F811
    session = session_of(gcp_block, tmp_path / "cache")
    for point_id in gcp_block["inside"][:3]:
        measure(session, gcp_block, point_id)
    dem = str(gcp_block["result"].dem)
    for target, what in ((gcp_block["displays"]["fwd"], "fwd/NAD (display copy)"), (dem, "DEM")):
        with pytest.raises(OutputError, match=re.escape(f"is the file of {what}")):
            session.save(target, dem)
    path = tmp_path / "gcps.gpkg"
    assert session.save(str(path), dem) == f"6 observations of 3 points saved to {path}"
    adjusted = read_gpkg(path)
    n = len(adjusted)
    adjusted.residuals = Residuals(np.full(n, 0.3), np.full(n, -0.4), np.full(n, 0.5), np.full(n, 1.0),
                                   np.ones(n, bool))
    write_gpkg(adjusted, tmp_path / "adjusted.gpkg")
    again = session_of(gcp_block, tmp_path / "cache")
    assert again.open_layer(str(tmp_path / "adjusted.gpkg")) == (f"3 points read from {tmp_path / 'adjusted.gpkg'}, "
                                                                 "6 observations with their residuals")
    np.testing.assert_allclose(again.editor.table().col, session.editor.table().col, rtol=0, atol=1e-9)
    rows = point_rows(again.editor.points, "nad", "NAD")
    assert [cells[3] for cells, _ in rows] == [("0.50", 0.5)] * 3          # hypot(0.3, -0.4)
    assert rows[0][1].startswith("nad/NAD: col") and ", residual +0.30, -0.40 px" in rows[0][1]
    assert [cells[5][0] for cells, _ in rows] == ["the layer adjusted.gpkg"] * 3


def test_rows_sort_ids_naturally_and_blank_what_is_missing():
    points = [MeasuredPoint("G10", observations=[Observation("a", "NAD", 1.0, 2.0)]), MeasuredPoint("G2")]
    rows = point_rows(points, "a", "NAD")
    assert sorted(cells[0][1] for cells, _ in rows)[0] == rows[1][0][0][1]           # G2 before G10
    assert rows[0][0][2] == ("1", 1) and rows[0][0][3] == ("", -1.0) and rows[1][0][4] == ("", -np.inf)
    assert rows[1][0][5] == ("no ground yet", None) and rows[1][1] == ""


def test_the_nearest_reference_point_within_the_tolerance():
    """Map units of 0.5 m per screen px: a click 3 m from a point (6 px) takes it, its Z kept (None
    without one); 15 m from every point (30 px) takes none, naming the distance."""
    xy = np.array([[100.0, 200.0], [130.0, 200.0]])
    lonlatz = np.array([[10.0, 45.0, 120.5], [10.001, 45.0, np.nan]])
    assert nearest_reference("ref", xy, lonlatz, (103.0, 200.0), 0.5, 20) == (10.0, 45.0, 120.5)
    assert nearest_reference("ref", xy, lonlatz, (129.0, 199.0), 0.5, 20) == (10.001, 45.0, None)
    with pytest.raises(InputError, match="within 20 screen px of the click \\(the nearest is 30 px away\\)"):
        nearest_reference("ref", xy, lonlatz, (115.0, 200.0), 0.5, 20)
    with pytest.raises(InputError, match="^The reference layer ref holds no point$"):
        nearest_reference("ref", [], [], (0.0, 0.0), 0.5, 20)
