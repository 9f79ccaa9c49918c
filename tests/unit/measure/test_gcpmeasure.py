"""Measuring GCPs in the scenes of a block without a user interface (core.measure.gcpmeasure,
core.measure.pointsnap), on a rendered block of two scenes with known truth (tests/support/gcpblock.py):
the editor's changes and undo, the GCP table and its GeoPackage round trip (one id in two scenes),
predictions of a point in the other scene through the true models, and Snap between scenes and to
the reference orthoimage, with weak matches refused."""
from pathlib import Path

import numpy as np
import pytest

from pushbroom_adjust.core.dem import ConstantHeight, Dem
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.measure.gcpmeasure import (Ground, PointEditor, predict, snap_to_reference, snap_to_scene,
                                                      surface_for)
from pushbroom_adjust.core.measure.pointsnap import PointSnapSettings
from pushbroom_adjust.core.measure.tiematching import View
from pushbroom_adjust.core.observations.gcps import read_gpkg, write_gpkg
from pushbroom_adjust.core.observations.tables import Heights
from tests.support.dems import read_dem, with_holes
from tests.support.gcpblock import NAMES, gcp_block, true_ground, true_pixel  # noqa: F401 (the fixture)

SIZE = (500, 500)


def views(block, models: str = "true") -> dict:
    return {n: View(n, block[models][n], 0, Path(block["result"].members[n]["images"]["NAD"])) for n in NAMES}


def measured(block, point_id: str, offsets=None) -> PointEditor:
    """An editor with ``point_id`` measured at its true pixel (+ offsets {scene: (dcol, drow)}) in
    both scenes, its ground the truth."""
    editor = PointEditor()
    editor.new_point(point_id)
    for name in NAMES:
        editor.measure(name, "NAD", *(true_pixel(block, point_id, name) + (offsets or {}).get(name, 0.0)), SIZE)
    editor.set_ground(Ground(*true_ground(block, point_id)))
    return editor


def test_editor_measures_moves_deletes_and_undoes_in_order():
    editor = PointEditor()
    assert editor.undo() == ""                                   # nothing to undo
    with pytest.raises(InputError, match="no point selected"):
        editor.measure("a", "NAD", 10.0, 10.0, SIZE)
    assert editor.new_point() == 0 and editor.current().id == "G1"
    assert editor.measure("a", "NAD", 10.0, 20.0, SIZE) == "measured"
    assert editor.measure("a", "NAD", 11.0, 21.0, SIZE) == "moved"
    assert editor.measure("b", "NAD", 30.0, 40.0, SIZE) == "measured"
    with pytest.raises(InputError, match=r"\(500.5, 3.0\) px is outside the image of b \(500 x 500 px\)"):
        editor.measure("b", "NAD", 500.5, 3.0, SIZE)
    with pytest.raises(InputError, match="there is a point 'G1' already"):
        editor.new_point("G1")
    editor.new_point()
    assert editor.current().id == "G2"
    editor.edit(point_id="P7", role="check")
    editor.edit(point_id="P7", role="check")                     # no change: nothing to undo
    with pytest.raises(InputError, match="sigma_px of point P7 must be > 0"):
        editor.edit(sigma_px=("a", "NAD", 0.0))
    assert editor.ids() == ["G1", "P7"] and editor.current().role == "check"
    assert [editor.undo() for _ in range(2)] == ["edit", "new point"] and editor.ids() == ["G1"]
    editor.select(0)
    assert editor.undo() == "measure" and len(editor.current().observations) == 1
    assert editor.undo() == "move" and (editor.current().observations[0].col,
                                         editor.current().observations[0].row) == (10.0, 20.0)
    assert editor.delete_selected() and editor.ids() == []
    assert editor.undo() == "delete point" and editor.ids() == ["G1"]


def test_table_round_trips_one_id_in_two_scenes_through_the_geopackage(gcp_block, tmp_path):  # noqa: F811
    editor = measured(gcp_block, "G1")
    editor.new_point("G3")
    editor.measure("fwd", "NAD", *true_pixel(gcp_block, "G3", "fwd"), SIZE)
    with pytest.raises(InputError, match="point\\(s\\) G3 have no ground position"):
        editor.table()
    editor.set_ground(Ground(*true_ground(gcp_block, "G3"), sigma_xy=0.5, sigma_z=2.0, source="reference"))
    editor.edit(sigma_px=("fwd", "NAD", 0.2))
    table = editor.table()
    assert table.id.tolist() == ["G1", "G1", "G3"] and table.scene.tolist() == ["nad", "fwd", "fwd"]
    write_gpkg(table, tmp_path / "gcps.gpkg")
    back = read_gpkg(tmp_path / "gcps.gpkg")
    reopened = PointEditor()
    reopened.load(back, list(NAMES))
    again = reopened.table()
    for field in ("id", "role", "camera", "scene"):
        assert getattr(again, field).tolist() == getattr(table, field).tolist()
    for field in ("col", "row", "lon", "lat", "h", "sigma_px", "sigma_xy", "sigma_z"):
        np.testing.assert_allclose(getattr(again, field), getattr(table, field), rtol=0, atol=1e-9)
    assert [p.ground.source for p in reopened.points] == ["layer", "layer"] and reopened.history == []
    with pytest.raises(InputError, match="names scene\\(s\\) 'fwd' that are not in the block \\(nad\\)"):
        PointEditor().load(back, ["nad"], "gcps.gpkg")


def test_predictions_through_the_true_models_meet_the_truth(gcp_block):  # noqa: F811
    """In fwd, point by point: from the true ground 0.000 px; from the nad observation on the DEM
    measured below 0.1 px (the DEM's bilinear surface against the simulator's terrain)."""
    dem = Dem(gcp_block["result"].dem, "geoid")
    all_views = views(gcp_block)
    for point_id in gcp_block["inside"]:
        editor = measured(gcp_block, point_id)
        got = {p.source: np.array([p.col, p.row]) for p in predict(editor.current(), all_views["fwd"], all_views, dem)}
        truth = true_pixel(gcp_block, point_id, "fwd")
        assert set(got) == {"ground", "nad"}
        assert np.hypot(*(got["ground"] - truth)) < 0.01
        assert np.hypot(*(got["nad"] - truth)) < 0.1, (point_id, got["nad"] - truth)
    onboard = views(gcp_block, "onboard")
    off = predict(measured(gcp_block, gcp_block["inside"][0]).current(), onboard["fwd"], onboard, dem)
    assert all(np.hypot(p.col - truth[0], p.row - truth[1]) > 2.0 for p in off for truth in
               [true_pixel(gcp_block, gcp_block["inside"][0], "fwd")])   # the onboard models are off


def test_a_prediction_through_a_dem_hole_has_no_position(gcp_block, tmp_path):  # noqa: F811
    """The nad observation's ray meets the DEM only on a hole: its prediction is NaN (no error about
    NaN ground coordinates), the one from the ground stays."""
    point_id = gcp_block["inside"][0]
    lon, lat, _ = true_ground(gcp_block, point_id)
    z, gt, _ = read_dem(gcp_block["result"].dem)
    mask = np.zeros(z.shape, bool)
    i, j = int((lat - gt[3]) / gt[5]), int((lon - gt[0]) / gt[1])
    mask[i - 3:i + 4, j - 3:j + 4] = True
    dem = Dem(with_holes(gcp_block["result"].dem, tmp_path / "holes.tif", mask), "geoid")
    all_views = views(gcp_block)
    got = {p.source: (p.col, p.row) for p in predict(measured(gcp_block, point_id).current(), all_views["fwd"],
                                                      all_views, dem)}
    assert np.isnan(got["nad"]).all() and np.hypot(*(np.array(got["ground"]) - true_pixel(gcp_block, point_id,
                                                                                            "fwd"))) < 0.01


def test_snap_between_scenes_recovers_the_true_pixel(gcp_block):  # noqa: F811
    """Clicks 1.5-2.5 px off in fwd, snapped to the nad observation (at the truth) through the
    onboard models: measured 0.001-0.021 px from the truth over 8 points, sigma at most 0.1 px."""
    dem = Dem(gcp_block["result"].dem, "geoid")
    all_views = views(gcp_block, "onboard")
    rng = np.random.default_rng(4)
    errors = []
    for point_id in gcp_block["inside"]:
        offset = rng.uniform(1.5, 2.5) * np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
        editor = measured(gcp_block, point_id, {"fwd": offset})
        snap = snap_to_scene(editor.current(), all_views["fwd"], all_views["nad"], dem)
        editor.snapped("fwd", "NAD", snap)
        seen = editor.current().observation("fwd", "NAD")
        errors.append(np.hypot(seen.col - true_pixel(gcp_block, point_id, "fwd")[0],
                               seen.row - true_pixel(gcp_block, point_id, "fwd")[1]))
        assert np.hypot(*snap.shift) == pytest.approx(np.hypot(*offset), abs=0.1)
        assert 0.0 < snap.sigma_px <= 0.1 and snap.correlation > 0.95
        assert editor.undo() == "snap"
    print(f"snap between scenes: {len(errors)} points, error {np.min(errors):.3f}-{np.max(errors):.3f} px")
    assert len(errors) >= 4 and max(errors) < 0.05


def test_snap_to_the_reference_orthoimage(gcp_block):  # noqa: F811
    """Against the reference orthoimage at the true ground: the points where the match is clear
    (others are refused as weak or ambiguous) come within 0.2 px of the truth. Measured: 7 of 8
    snapped, 0.03-0.13 px (the reference's own pixels are resampled), 1 refused."""
    dem = Dem(gcp_block["result"].dem, "geoid")
    all_views = views(gcp_block, "onboard")
    errors, refused = [], []
    for point_id in gcp_block["inside"]:
        editor = measured(gcp_block, point_id, {"fwd": np.array([1.2, -0.9])})
        try:
            snap = snap_to_reference(editor.current(), all_views["fwd"], gcp_block["result"].reference, dem)
        except InputError as exc:
            refused.append(str(exc))
            continue
        errors.append(np.hypot(*(np.array([snap.col, snap.row]) - true_pixel(gcp_block, point_id, "fwd"))))
    print(f"snap to the reference: {len(errors)} snapped, error max {max(errors):.3f} px; {len(refused)} refused")
    assert len(errors) >= 4 and max(errors) < 0.2
    assert all("snapping:" in r and "the click is kept" in r for r in refused)


def test_weak_matches_are_refused_naming_why(gcp_block):  # noqa: F811
    dem = Dem(gcp_block["result"].dem, "geoid")
    all_views = views(gcp_block, "onboard")
    point_id = gcp_block["inside"][0]
    far = measured(gcp_block, point_id, {"fwd": np.array([25.0, 0.0])})    # beyond the search radius
    with pytest.raises(InputError, match="best correlation with nad \\(NAD\\) is 0\\.[0-6]|ambiguous"):
        snap_to_scene(far.current(), all_views["fwd"], all_views["nad"], dem)
    edge = PointEditor()
    edge.new_point("E")
    edge.measure("nad", "NAD", 250.0, 250.0, SIZE)
    edge.measure("fwd", "NAD", 4.0, 250.0, SIZE)
    with pytest.raises(InputError, match=r"\(4.0, 250.0\) px is within 16 px of the image's edge"):
        snap_to_scene(edge.current(), all_views["fwd"], all_views["nad"], dem)
    with pytest.raises(InputError, match="point E is not measured in nad2"):
        snap_to_scene(edge.current(), all_views["fwd"], View("nad2", all_views["nad"].scene, 0, all_views["nad"].image),
                      dem)
    with pytest.raises(InputError, match="odd window"):
        snap_to_scene(measured(gcp_block, point_id).current(), all_views["fwd"], all_views["nad"], dem,
                      PointSnapSettings(window=20))


def test_surfaces_from_heights(gcp_block):  # noqa: F811
    view = views(gcp_block)["nad"]
    assert isinstance(surface_for(Heights("dem", "geoid", str(gcp_block["result"].dem)), view), Dem)
    flat = surface_for(Heights("constant", "ellipsoid", None, 250.0), view)
    assert isinstance(flat, ConstantHeight) and flat.value == 250.0
    with pytest.raises(InputError, match="no DEM was given"):
        surface_for(Heights("dem", "geoid", None), view)
