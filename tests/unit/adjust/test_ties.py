"""Tie points in the bundle adjustment (simulated TH-1 three-line blocks with known truth):
truth recovery with 4 and 1 GCPs, free networks held by the onboard pseudo-observations, the
datum defect named, single rays left out, gross errors flagged, multi-camera GCPs."""
import csv
import logging
from dataclasses import fields, replace

import numpy as np
import pytest

from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.adjust.linepoints import ControlLines
from pushbroom_adjust.core.adjust.ties import datum
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.model.intersection import intersect
from pushbroom_adjust.core.observations.lines import read_ground_lines, read_image_lines
from pushbroom_adjust.simulation.roads import RoadSettings
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.presets import ErrorSettings
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate
from pushbroom_adjust.core.observations.tiepoints import TieTable

ARCSEC = np.pi / 648000.0

NOISE = 0.3  # px
# the simulated trajectory errors only: the interior is exact, so the figures are the engine's
TRAJECTORY_ONLY = {f.name: 0.0 for f in fields(ErrorSettings) if not f.name.startswith(("position", "attitude"))}


def _ties(path, sigma=NOISE) -> tuple[TieTable, np.ndarray]:
    """The simulated tie CSV as a TieTable, and the true ECEF position (n,3) per observation."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    table = TieTable(col["id"], col["camera"], col["col"].astype(float), col["row"].astype(float), sigma, "")
    truth = geodetic_to_ecef(*(col[k].astype(float) for k in ("lon_true", "lat_true", "h_true")))
    return table, truth


def _gcps(result) -> G.GcpTable:
    return G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                      Heights("z", datum="ellipsoid"), sigma_px=NOISE, sigma_xy=0.01, sigma_z=0.01)


@pytest.fixture(scope="module")
def th1(tmp_path_factory):
    """TH-1 block: 40 GCPs (half check points), 100 tie points, 0.3 px noise."""
    result = simulate("th1_tlc", tmp_path_factory.mktemp("th1ties"), seed=5, errors=TRAJECTORY_ONLY,
                      gcp_settings=GcpSettings(n_gcps=40, check_fraction=0.5, image_noise=NOISE, n_tie_points=100))
    ties, truth = _ties(result.tie_points)
    return load_scene(result.onboard_scene), _gcps(result), ties, truth


def _corner_control(table: G.GcpTable, k: int) -> G.GcpTable:
    """The check points and the k control points nearest the corners of the nadir image."""
    control = (table.role == "control") & (table.camera == "NAD")
    ids = table.id[control]
    xy = np.stack([table.col[control] / 12000.0, table.row[control] / 12000.0], axis=1)
    corners = np.array([[0, 0], [1, 1], [0, 1], [1, 0]])[:k]
    chosen = ids[[int(np.argmin(np.linalg.norm(xy - c, axis=1))) for c in corners]]
    return table.select(np.isin(table.id, chosen) | (table.role == "check"))


def _tie_errors(out, truth) -> np.ndarray:
    """(n,3) ECEF m: adjusted minus true ground position per tie observation."""
    t = out.tie_points
    return geodetic_to_ecef(t["lon"], t["lat"], t["h"]) - truth


def test_four_gcps_and_tie_points_recover_the_true_ground(th1):
    scene, table, ties, truth = th1
    out = adjust(scene, _corner_control(table, 4), AdjustmentSettings(position_sigma=100.0), ties=ties)
    rep = out.report
    error = np.linalg.norm(_tie_errors(out, truth), axis=1)
    # measured: median 2.95 m, max 7.6 m (5 m GSD, 0.3 px, +-25 deg stereo)
    assert np.median(error) < 3.5
    assert error.max() < 9.0
    assert rep["datum"]["held_by"] == "control points and onboard pseudo-observations"
    assert rep["observations"]["control_points"] == 4
    assert rep["observations"]["tie_points"]["points"] == 100
    assert rep["observations"]["tie_observations"] == len(ties)
    tr = rep["tie_points"]
    for cam in ("NAD", "FWD", "BWD"):
        assert 0.1 < tr["residuals_per_camera"][cam]["rmse_col"] < NOISE
    assert tr["flagged"] <= 3            # no gross errors simulated: alpha 0.001 on ~900 observations
    assert rep["sigma0"] == pytest.approx(1.0, abs=0.15)
    assert set(out.tie_points) >= {"id", "camera", "col", "row", "res_col", "res_row", "w_col", "w_row", "flagged",
                                   "weight", "lon", "lat", "h"}
    assert np.array_equal(out.tie_points["id"], ties.id)


def test_free_network_held_by_onboard_pseudo_observations(th1):
    scene, table, ties, truth = th1
    out = adjust(scene, table.select(table.role == "check"),
                 AdjustmentSettings(position_sigma=20.0, attitude_sigma=1e-4), ties=ties)
    rep = out.report
    assert rep["datum"]["held_by"] == "onboard pseudo-observations"
    assert "absolute accuracy is that of the onboard orbit and attitude" in rep["datum"]["note"]
    assert rep["observations"]["control_points"] == 0
    # relative geometry: image residuals at the noise, the ground errors one common offset
    for cam in ("NAD", "FWD", "BWD"):
        assert rep["tie_points"]["residuals_per_camera"][cam]["rmse_col"] < NOISE
    errors = _tie_errors(out, truth)
    offset = errors.mean(axis=0)
    spread = np.linalg.norm(errors - offset, axis=1)
    # absolute: about the onboard error (the forward intersection with the onboard model)
    ids, point = ties.points()
    onboard = np.linalg.norm(intersect(scene, [["NAD", "FWD", "BWD"].index(c) for c in ties.camera], ties.col,
                                       ties.row, point).ground[point] - truth, axis=1)
    # measured: offset 45.9 m, onboard error 58 m (median); spread about the offset median 2.5 m
    assert 0.5 * np.median(onboard) < np.linalg.norm(offset) < 1.5 * np.median(onboard)
    assert np.linalg.norm(offset) > 20.0
    assert np.median(spread) < 5.0


def test_one_gcp_adjusts_the_block(th1):
    scene, table, ties, truth = th1
    out = adjust(scene, _corner_control(table, 1), AdjustmentSettings(position_sigma=100.0), ties=ties)
    error = np.linalg.norm(_tie_errors(out, truth), axis=1)
    # measured: median 2.96 m, max 9.8 m
    assert np.median(error) < 3.5
    assert error.max() < 12.0
    assert out.report["datum"]["held_by"] == "control points and onboard pseudo-observations"
    assert "1 control point(s)" in out.report["datum"]["note"]


@pytest.mark.parametrize("k, position, attitude, named", [
    (0, None, None, ["shift X, shift Y, shift Z", "roll", "pitch", "yaw", "scale", "POSITION_SIGMA",
                     "ATTITUDE_SIGMA", "at least 3 well spread GCPs"]),
    (0, 100.0, None, ["not roll (rotation about the flight line)", "ATTITUDE_SIGMA"]),
    (1, None, None, ["not roll (rotation about the flight line), pitch, yaw, scale", "POSITION_SIGMA"]),
    (2, None, None, ["rotation about the line through the 2 control points"]),
])
def test_the_datum_defect_is_named(th1, k, position, attitude, named):
    scene, table, ties, _ = th1
    with pytest.raises(InputError, match="datum defect") as err:
        adjust(scene, _corner_control(table, k), AdjustmentSettings(position_sigma=position, attitude_sigma=attitude),
               ties=ties)
    for text in named:
        assert text in str(err.value)


def test_datum_with_attitude_only_lacks_shift_and_scale():
    with pytest.raises(InputError, match=r"not shift X, shift Y, shift Z, scale; .*Give POSITION_SIGMA"):
        datum(0, None, 1e-5)
    assert datum(3, None, None)["held_by"] == "control points"


def test_datum_credits_control_lines():
    """Lines in several directions hold every component (as 3+ GCPs); lines all running one way
    only the height, roll and pitch."""
    one = datum(1, None, None, n_lines=20, lines_determined=True)
    assert one["held_by"] == "control points and control lines" and one["control_lines"] == 20
    assert one["note"] == "1 control point(s): the datum components they do not hold are held by the control lines"
    assert datum(0, None, None, n_lines=20, lines_determined=True)["held_by"] == "control lines"
    assert datum(2, None, None, n_lines=5, lines_determined=True)["components"]["yaw"] == ["control points",
                                                                                         "control lines"]
    assert datum(1, 100.0, None, 20, True)["held_by"] == ("control points, control lines and onboard "
                                                          "pseudo-observations")
    with pytest.raises(InputError, match=r"1 control point\(s\), 20 control line\(s\) all running one way and no "
                                         r"onboard .* but not yaw, scale; .*Give POSITION_SIGMA .* and ATTITUDE_SIGMA"):
        datum(1, None, None, n_lines=20, lines_determined=False)


def _yaw_sentence(rep: dict) -> str:
    return f"the yaw (block rotation about the vertical) is held to {rep['datum']['yaw']['sigma_arcsec']:.1f} arcsec"


def test_the_yaw_sigma_follows_the_attitude_prior(th1):
    """1 GCP: the yaw is held by the onboard data, as tightly as their sigmas and the tie points
    allow; the posterior sigma (from the solution's covariance) never exceeds the attitude prior's
    and shrinks with it. Its effect at the scene's corners is the sigma times their distance from
    the centre (half the 60 km x 60 km nadir footprint's diagonal)."""
    scene, table, ties, _ = th1
    yaw = {}
    for attitude in (None, 1e-4, 1e-5):  # rad: 20.6 and 2.06 arcsec
        rep = adjust(scene, _corner_control(table, 1), AdjustmentSettings(position_sigma=100.0,
                                                                          attitude_sigma=attitude), ties=ties).report
        yaw[attitude] = rep["datum"]["yaw"]
        assert _yaw_sentence(rep) in rep["datum"]["note"]
    # measured: 52.0, 11.4, 1.2 arcsec; 10.7, 2.3, 0.25 m at 42.4 km
    assert yaw[None]["sigma_arcsec"] > 2 * yaw[1e-4]["sigma_arcsec"] > 4 * yaw[1e-5]["sigma_arcsec"]
    assert yaw[1e-4]["sigma_arcsec"] < 1e-4 / ARCSEC and yaw[1e-5]["sigma_arcsec"] < 1e-5 / ARCSEC
    for y in yaw.values():
        assert y["radius_m"] == pytest.approx(np.hypot(30e3, 30e3), rel=0.03)
        assert y["edge_m"] == pytest.approx(y["sigma_arcsec"] * ARCSEC * y["radius_m"], rel=1e-9)


def test_one_gcp_and_control_lines_hold_the_datum(tmp_path):
    """A TH-1 block with 1 GCP, tie points and 20 roads as control lines, without onboard sigmas:
    the datum is held by the GCP and the lines (a defect without the lines), the yaw to a few arcsec."""
    result = simulate("th1_tlc", tmp_path, seed=5, errors=TRAJECTORY_ONLY,
                      gcp_settings=GcpSettings(n_gcps=40, check_fraction=0.5, image_noise=NOISE, n_tie_points=100),
                      road_settings=RoadSettings(n_lines=20))
    scene, table, (ties, _) = load_scene(result.onboard_scene), _gcps(result), _ties(result.tie_points)
    lines = ControlLines(read_ground_lines(result.lines), read_image_lines(result.lines))
    settings = AdjustmentSettings(position_sigma=None)
    with pytest.raises(InputError, match="datum defect"):
        adjust(scene, _corner_control(table, 1), settings, ties=ties)
    rep = adjust(scene, _corner_control(table, 1), settings, ties=ties, lines=lines).report
    assert rep["datum"]["held_by"] == "control points and control lines"
    assert rep["datum"]["control_points"] == 1 and rep["datum"]["control_lines"] == 20
    assert rep["datum"]["note"].startswith("1 control point(s): the datum components they do not hold are held by "
                                           "the control lines; " + _yaw_sentence(rep))
    # measured: 2.2 arcsec (0.45 m at the corners); check points 1.24 m plan
    assert rep["datum"]["yaw"]["sigma_arcsec"] < 5.0
    assert rep["check_points"]["intersection"]["rmse_plan"] < 2.0


def test_a_tie_point_with_one_ray_is_left_out_and_named(th1, caplog):
    scene, table, ties, truth = th1
    ids, point = ties.points()
    counts = np.bincount(point)
    lonely = ids[np.nonzero(counts == 3)[0][0]]
    drop = np.nonzero(ties.id == lonely)[0][:2]
    cut = ties.select(~np.isin(np.arange(len(ties)), drop))
    with caplog.at_level(logging.WARNING):
        out = adjust(scene, _corner_control(table, 4), AdjustmentSettings(position_sigma=100.0), ties=cut)
    assert "1 tie point(s) seen by one camera only are left out" in caplog.text and lonely in caplog.text
    counts = out.report["observations"]["tie_points"]
    assert counts["points"] == 99 and counts["observations"] == len(cut) - 1
    assert counts["left_out"] == {"single_ray": {"points": 1, "ids": [lonely]}}
    alone = out.tie_points["id"] == lonely
    assert np.isnan(out.tie_points["lon"][alone]).all() and np.isnan(out.tie_points["res_col"][alone]).all()
    assert np.isfinite(out.tie_points["lon"][~alone]).all()


def test_gross_errors_in_tie_observations_are_flagged_not_deleted(th1):
    scene, table, ties, truth = th1
    ids, point = ties.points()
    three = np.nonzero(np.bincount(point)[point] == 3)[0]
    bad = three[::9][:12]  # observations of 3-ray points (a 2-ray point's error cannot be told from its partner)
    angle = np.linspace(0.0, 2 * np.pi, bad.size, endpoint=False)
    gross = replace(ties, col=ties.col.copy(), row=ties.row.copy())
    gross.col[bad] += 8.0 * np.cos(angle)
    gross.row[bad] += 8.0 * np.sin(angle)
    for method in ("selection", "snooping"):
        out = adjust(scene, _corner_control(table, 4), AdjustmentSettings(position_sigma=100.0, robust=method),
                     ties=gross)
        t = out.tie_points
        is_bad = np.isin(np.arange(len(ties)), bad)
        assert t["flagged"][is_bad].all(), method
        # Along track (row) a 3-ray point has one redundancy: its rays' row residuals share one
        # normalised value, so a row error is found but may be blamed on a partner ray as well.
        partner = ~is_bad & np.isin(ties.id, ties.id[bad])
        assert t["flagged"][~is_bad & ~partner].sum() <= 3, method
        assert np.all(t["weight"][is_bad] < 0.1), method
        assert out.report["tie_points"]["flagged"] == int(t["flagged"].sum())
        assert set(out.report["robust"]["flagged_tie_ids"]) == set(ties.id[t["flagged"]])
        # the solution is not spoiled
        assert np.median(np.linalg.norm(_tie_errors(out, truth), axis=1)) < 3.5, method


def test_gcps_in_all_three_cameras(th1):
    """One GCP id measured in every camera that sees it: all its rows enter the adjustment."""
    scene, table, _, _ = th1
    control = table.role == "control"
    _, per_id = np.unique(table.id[control], return_counts=True)
    assert (per_id == 3).sum() >= 15
    out = adjust(scene, table, AdjustmentSettings(position_sigma=100.0, robust="none"))
    rep = out.report
    assert rep["observations"]["control_points"] == per_id.size
    assert rep["observations"]["image_observations"] == int(control.sum())
    assert np.isfinite(out.points["res_col"][control]).all()
    assert rep["check_points"]["image"]["rmse"] < 1.5 * NOISE
    assert "datum" not in rep and "tie_points" not in rep


def test_bad_tie_input_is_refused_with_names(th1):
    scene, table, ties, _ = th1
    settings = AdjustmentSettings(position_sigma=100.0)
    control = _corner_control(table, 4)
    other = replace(ties, camera=ties.camera.copy())
    other.camera[3] = "PAN"
    with pytest.raises(InputError, match=rf"camera\(s\) PAN of point\(s\) {ties.id[3]} not in the scene"):
        adjust(scene, control, settings, ties=other)
    twice = ties.select(np.r_[np.arange(len(ties)), 0])
    with pytest.raises(InputError, match=rf"point\(s\) {ties.id[0]} are observed more than once in the same camera"):
        adjust(scene, control, settings, ties=twice)
    outside = replace(ties, col=ties.col.copy())
    outside.col[5] = -40.0
    with pytest.raises(InputError, match=rf"observation\(s\) of point\(s\) {ties.id[5]} lie outside"):
        adjust(scene, control, settings, ties=outside)
    clash = replace(ties, id=ties.id.copy())
    clash.id[ties.id == ties.id[0]] = control.id[0]
    with pytest.raises(InputError, match=rf"id\(s\) {control.id[0]} are also GCP ids"):
        adjust(scene, control, settings, ties=clash)


def test_redundancy_numbers_of_multi_ray_points_sum_to_the_degrees_of_freedom(th1):
    """The leverage of a tie point's rays includes their coupling through the shared ground
    unknowns: the redundancy numbers of all observations add up to the degrees of freedom
    (taking only each ray's own share gave too small redundancies and false gross errors)."""
    scene, table, ties, _ = th1
    out = adjust(scene, _corner_control(table, 4),
                 AdjustmentSettings(position_sigma=100.0, robust="none", variance_components=False), ties=ties)
    rep = out.report
    total = sum(v["redundancy"] for v in rep["variance_components"].values())
    assert total == pytest.approx(rep["observations"]["degrees_of_freedom"], abs=1e-3)
    assert rep["sigma0"] == pytest.approx(1.0, abs=0.15)


def test_html_report_tells_the_datum_and_tie_points(th1, tmp_path):
    from pushbroom_adjust.core.adjust.report_html import write_report_html
    scene, table, ties, _ = th1
    lonely = ties.select(~np.isin(np.arange(len(ties)), np.nonzero(ties.id == ties.id[0])[0][1:]))
    out = adjust(scene, table.select(table.role == "check"),
                 AdjustmentSettings(position_sigma=20.0, attitude_sigma=1e-4), ties=lonely)
    write_report_html(out.report, out.points, tmp_path / "r.html")
    text = (tmp_path / "r.html").read_text()
    assert "Datum held by onboard pseudo-observations (0 control points)" in text
    assert "absolute accuracy is that of the onboard orbit and attitude" in text
    assert f"tie points: 99 points, {len(lonely) - 1} of {len(lonely)} observations used" in text
    assert f"tie points left out: 1 seen by one camera only (one ray fixes no ground position): {ties.id[0]}" in text
    assert text.count("<h2>Tie points</h2>") == 1


def test_tie_points_in_one_corner_adjust_with_a_warning(th1, caplog):
    scene, table, ties, truth = th1
    nad = ties.camera == "NAD"
    corner = np.unique(ties.id[nad & (ties.col < 1100) & (ties.row < 1100)])
    assert corner.size >= 2
    some = ties.select(np.isin(ties.id, corner))
    with caplog.at_level(logging.WARNING):
        out = adjust(scene, _corner_control(table, 4), AdjustmentSettings(position_sigma=100.0), ties=some)
    assert "the tie points cover only" in caplog.text and "(one corner)" in caplog.text
    span = out.report["tie_points"]["span"]
    assert max(span) < 0.1
    error = np.linalg.norm(_tie_errors(out, truth[np.isin(ties.id, corner)]), axis=1)
    assert np.median(error) < 5.0


def test_fixed_ground_gcps_with_tie_unknowns(th1):
    """Fixed GCPs (no ground unknowns) next to the tie points' unknowns (no prior)."""
    scene, table, ties, truth = th1
    out = adjust(scene, _corner_control(table, 4), AdjustmentSettings(position_sigma=100.0, ground="fixed"), ties=ties)
    assert out.report["observations"]["ground_unknowns"] == 3 * 100
    error = np.linalg.norm(_tie_errors(out, truth), axis=1)
    assert np.median(error) < 3.5     # measured 2.95 m, as with weighted ground (sigma 0.01 m)
    assert out.report["sigma0"] == pytest.approx(1.0, abs=0.15)


def test_exact_tie_points_hold_their_variance_components_at_the_floor(tmp_path, caplog):
    """Noise-free tie points beside measured control points: when both shared each camera's image
    group, the first robust pass's scale, then the groups' variance components, followed the exact
    tie points towards 0 (measured on a TH-1 block: 0.027, 0.0004, < 0.0001 in three passes) and the
    run stopped without converging. The tie observations have a group of their own ("tie points")
    whose factor never goes below 1 (their stated sigmas; their estimates are reported,
    0.04 measured), the control points' groups are not pulled down with them, the run
    converges and the 3D check figures are those of a good block (measured: plan 1.46 m RMSE with 4
    GCPs, 5 m GSD)."""
    result = simulate("th1_tlc", tmp_path, seed=5, errors=TRAJECTORY_ONLY,
                      gcp_settings=GcpSettings(n_gcps=40, check_fraction=0.5, image_noise=NOISE, n_tie_points=100))
    with open(result.tie_points) as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    exact = TieTable(col["id"], col["camera"], col["col_true"].astype(float), col["row_true"].astype(float), NOISE, "")
    with caplog.at_level(logging.WARNING, logger="pushbroom_adjust.core.adjust.robust"):
        rep = adjust(load_scene(result.onboard_scene), _corner_control(_gcps(result), 4),
                     AdjustmentSettings(position_sigma=100.0, interior="default", interior_selection="keep"),
                     ties=exact).report
    assert not rep["robust"]["stopped_at_limit"]
    component = rep["variance_components"]["tie points"]
    assert component["held_at_floor"] and component["sigma0"] < 0.1
    for cam in ("NAD", "FWD", "BWD"):
        assert not rep["variance_components"][f"image {cam}"]["held_at_floor"]
    assert "held at 0.01" not in caplog.text
    assert rep["check_points"]["intersection"]["rmse_plan"] < 2.0
