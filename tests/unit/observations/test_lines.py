"""Control lines (core.observations.lines, linemodel): the rank-2 line constraint, nearest-segment association, its
first-order equivalence with the coplanarity condition of Tommaselli & Marcato Junior 2012
(eq. 4), geometry checks, direction checks and the GeoPackage layers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, enu_rotation, geodetic_to_ecef, up_vector
from pushbroom_adjust.core.observations.linemodel import (LineSegments, check_image_lines, check_in_scene,
                                                          coplanarity_residual, direction_check, line_constraints,
                                                          nearest_segments, pair, segment_directions, start_points)
from pushbroom_adjust.core.observations.lines import (GroundLines, ImageLines, build_ground_lines, build_image_lines,
                                                      read_ground_lines, read_image_lines, write_gpkg)
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.simulator import simulate

FLAT = Heights("constant", "ellipsoid", value=300.0)
LON0, LAT0 = 114.0, 34.5


def _lonlat(e, n):
    """(lon, lat) of local east/north metres about (LON0, LAT0)."""
    return LON0 + e / (111320.0 * math.cos(math.radians(LAT0))), LAT0 + n / 110574.0


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    result = simulate("cbers02b_hrc", tmp_path_factory.mktemp("lines") / "sim", seed=2, n_gcps=10, n_lines=12)
    return load_scene(result.true_scene), Dem(result.dem, datum="geoid"), result


# --- the rank-2 constraint -----------------------------------------------------------------------
def test_weight_is_rank_2_zero_along_the_line_and_stated_across_and_in_height():
    lon, lat = _lonlat(np.array([0.0, 800.0]), np.array([0.0, 600.0]))   # azimuth 53.13 deg
    ground = GroundLines(["A"], [0, 2], lon, lat, [300.0, 380.0], 2.0, 5.0)  # sloped: 80 m over 1 km
    seg = LineSegments.from_lines(ground)
    x = geodetic_to_ecef(*_lonlat(np.array([400.0]), np.array([300.0])), np.array([400.0]))
    c = line_constraints(seg, np.array([0]), x)
    w = c.weight[0]
    assert np.linalg.matrix_rank(w, tol=1e-9) == 2
    assert np.linalg.norm(w @ c.along[0]) < 1e-12
    assert c.across[0] @ w @ c.across[0] == pytest.approx(1 / 2.0 ** 2, rel=1e-12)
    assert c.normal[0] @ w @ c.normal[0] == pytest.approx(1 / 5.0 ** 2, rel=1e-12)
    up = up_vector(*ecef_to_geodetic(c.foot)[:2])[0]
    assert abs(c.across[0] @ up) < 1e-12                         # across is horizontal
    assert math.degrees(math.acos(c.normal[0] @ up)) == pytest.approx(math.degrees(math.atan(80 / 1000)), abs=0.01)
    # the point sits at the line's middle, 60 m above it (the line is at 340 m there)
    assert c.d_across[0] == pytest.approx(0.0, abs=0.05)
    assert c.d_normal[0] == pytest.approx(60.0 * math.cos(math.atan(0.08)), abs=0.05)
    # variance-component factors scale the stated sigmas
    c2 = line_constraints(seg, np.array([0]), x, across_factor=2.0, height_factor=0.5)
    assert c2.across[0] @ c2.weight[0] @ c2.across[0] == pytest.approx(1 / 4.0 ** 2)
    assert c2.normal[0] @ c2.weight[0] @ c2.normal[0] == pytest.approx(1 / 2.5 ** 2)


def test_points_associate_with_the_nearest_segment_of_a_curved_polyline():
    # an arc of radius 1000 m over 90 deg, 19 segments; points 10 m outside (and 50 m too high)
    angle = np.linspace(0.0, math.pi / 2, 20)
    e, n = 1000.0 * np.cos(angle), 1000.0 * np.sin(angle)
    lon, lat = _lonlat(e, n)
    ground = GroundLines(["C"], [0, 20], lon, lat, 300.0, 1.0, 1.0)
    seg = LineSegments.from_lines(ground)
    mid = 0.5 * (angle[1:] + angle[:-1])
    reach = 1010.0 * math.cos(0.5 * (angle[1] - angle[0]))      # the chord midpoints' radius + 10 m
    lon_p, lat_p = _lonlat(reach * np.cos(mid), reach * np.sin(mid))
    x = geodetic_to_ecef(lon_p, lat_p, np.full(mid.size, 350.0))
    s, t = nearest_segments(seg, np.zeros(mid.size, np.int64), x)
    assert np.array_equal(s, np.arange(19))
    assert np.allclose(t, 0.5, atol=0.01)
    c = line_constraints(seg, np.zeros(mid.size, np.int64), x)
    assert np.allclose(np.abs(c.d_across), 10.0, atol=0.05)       # 10 m outside the arc, every point
    assert np.allclose(c.d_normal, 50.0, atol=0.05)
    # moving a point along the arc re-associates it with the segment it now lies beside
    x2 = geodetic_to_ecef(*_lonlat(reach * np.cos(mid[5:6] + 0.05), reach * np.sin(mid[5:6] + 0.05)), [300.0])
    assert nearest_segments(seg, np.array([0]), x2)[0][0] == 6


def test_line_constraint_is_to_first_order_the_coplanarity_condition(sim):
    """A point measured 2 px across the image of a straight ground line: eliminating its
    ground point under a (near-hard) rank-2 line weight leaves a residual of 2 px, across the
    image line; the coplanarity condition (eq. 4) gives the same 2 px."""
    scene, dem, _ = sim
    ends = scene.image_to_ground_dem(np.array([3000.0, 3900.0]), np.array([5000.0, 5600.0]), dem, 0)
    lon, lat, h = ecef_to_geodetic(ends)
    ground = GroundLines(["L"], [0, 2], lon, lat, h, 0.01, 0.01)
    seg = LineSegments.from_lines(ground)
    col, row = scene.ground_to_image(ends, 0)
    mid = scene.ground_to_image(0.5 * (ends[0] + ends[1])[None], 0)
    direction = np.array([col[1] - col[0], row[1] - row[0]])
    across_img = np.array([-direction[1], direction[0]]) / np.linalg.norm(direction)
    delta = 2.0
    measured = np.array([mid[0][0], mid[1][0]]) + delta * across_img
    image = ImageLines(["L"], "HRC", [0, 2], [measured[0], measured[0] + 1e-3], [measured[1], measured[1]], 1.0)
    obs = pair(image, ground)
    x0 = start_points(scene, obs, seg)[:1]
    c = line_constraints(seg, obs.key[:1], x0)
    # image Jacobian by the ground point (px/m), by central differences
    jac = np.stack([np.subtract(*[np.array(scene.ground_to_image(x0 + s * np.eye(3)[k], 0))[:, 0]
                                  for s in (0.5, -0.5)]) for k in range(3)], axis=1)
    r = np.array(scene.ground_to_image(x0, 0))[:, 0] - measured
    P, W, e = np.eye(2), c.weight[0], c.misfit[0]
    K = np.linalg.inv(jac.T @ P @ jac + W)
    b = jac.T @ P @ r + W @ e
    chi2 = r @ P @ r + e @ W @ e - b @ K @ b
    reduced = P - P @ jac @ K @ jac.T @ P
    values, vectors = np.linalg.eigh(reduced)
    # coplanarity: the angle of the ray out of the plane (PC, line), in pixels across the image line
    cop = coplanarity_residual(scene, "HRC", measured[:1], measured[1:], ends[0], ends[1])[0]
    shifted = measured + across_img
    per_px = coplanarity_residual(scene, "HRC", shifted[:1], shifted[1:], ends[0], ends[1])[0] - cop
    print(f"eliminated line point: {math.sqrt(chi2):.4f} px; coplanarity: {cop / per_px:.4f} px")
    assert math.sqrt(chi2) == pytest.approx(delta, abs=0.01)
    assert abs(cop / per_px) == pytest.approx(delta, abs=0.01)
    assert values[0] == pytest.approx(0.0, abs=1e-3)                # one constraint left (rank 1) ...
    assert abs(vectors[:, 1] @ across_img) > 0.999                  # ... across the image line


# --- geometry checks ------------------------------------------------------------------------------
def _parts(*coords):
    return [np.array(c, dtype=float) for c in coords]


def test_a_line_layer_without_crs_is_refused():
    with pytest.raises(InputError, match="roads.gpkg: the line layer has no CRS"):
        build_ground_lines(["A"], _parts([(114.0, 34.5), (114.01, 34.5)]), crs=None, heights=FLAT,
                           source="roads.gpkg")


def test_lines_with_one_vertex_are_refused_by_name():
    with pytest.raises(InputError, match="line.s. B have fewer than two vertices"):
        build_image_lines(["A", "B"], _parts([(10, 10), (20, 20)], [(5, 5)]), "HRC")
    with pytest.raises(InputError, match="line.s. R2 have fewer than two vertices"):
        build_ground_lines(["R1", "R2"], _parts([(114.0, 34.5), (114.01, 34.5)], [(114.0, 34.6)]), crs="EPSG:4326",
                           heights=FLAT)


def test_zero_length_and_self_intersecting_lines_are_refused_by_name():
    with pytest.raises(InputError, match="line.s. Z have zero length"):
        build_image_lines(["Z"], _parts([(10, 10), (10, 10), (10, 10)]), "HRC")
    with pytest.raises(InputError, match="line.s. X intersect themselves"):
        build_image_lines(["X"], _parts([(0, 0), (10, 10), (10, 0), (0, 10)]), "HRC")
    with pytest.raises(InputError, match="line.s. G intersect themselves"):
        build_ground_lines(["G"], _parts([(114.0, 34.5), (114.01, 34.51), (114.01, 34.5), (114.0, 34.51)]),
                           crs="EPSG:4326", heights=FLAT)
    # a double click (a repeated vertex) is legitimate: dropped; a closed ring is accepted
    lines = build_image_lines(["D", "O"], _parts([(0, 0), (5, 5), (5, 5), (9, 9)],
                                                  [(0, 0), (10, 0), (10, 10), (0, 0)]), "HRC")
    assert list(lines.start) == [0, 3, 7]


def test_ids_that_pair_nothing_are_named():
    ground = build_ground_lines(["R1", "R2"], _parts([(114.0, 34.5), (114.01, 34.5)], [(114.0, 34.6), (114.0, 34.61)]),
                                crs="EPSG:4326", heights=FLAT)
    image = build_image_lines(["R1", "R9", "R7"], _parts([(1, 1), (9, 9)], [(2, 1), (8, 9)], [(3, 1), (7, 9)]), "HRC")
    with pytest.raises(InputError, match="line id.s. R7, R9 pair with no ground line"):
        pair(image, ground)


def test_ground_lines_outside_the_scene_and_image_lines_outside_the_image_are_named(sim):
    scene, dem, result = sim
    inside = ecef_to_geodetic(scene.image_to_ground(np.array([100.0, 900.0]), np.array([100.0, 900.0]), 300.0, 0))
    ground = build_ground_lines(["IN", "FAR"], _parts(np.stack(inside[:2], 1), [(100.0, -20.0), (100.01, -20.0)]),
                                crs="EPSG:4326", heights=FLAT)
    with pytest.raises(InputError, match="line.s. FAR lie outside the scene"):
        check_in_scene(ground, scene)
    check_in_scene(ground, scene, ids=["IN"])          # only the paired lines matter
    image = build_image_lines(["IN"], _parts([(10, 10), (-30, 40)]), "HRC")
    with pytest.raises(InputError, match="image line.s. IN lie outside the image"):
        check_image_lines(image, scene)
    with pytest.raises(InputError, match="camera.s. NAD of line.s. IN are not in the scene"):
        check_image_lines(build_image_lines(["IN"], _parts([(10, 10), (30, 40)]), "NAD"), scene)


def test_lines_that_all_run_one_way_are_named_with_the_free_direction():
    parallel = direction_check(np.radians([30.0, 31.0, 29.5, 30.5]))
    assert not parallel.determined
    assert parallel.azimuth_deg == pytest.approx(30.25, abs=0.1)
    assert "a shift along azimuth 30.2 deg is not determined" in parallel.message
    crossing = direction_check(np.radians([30.0, 120.0, 75.0]))
    assert crossing.determined and crossing.spread_deg > 30.0
    # two lines +-8 deg about north: spread 8 deg (the RMS angle)
    assert direction_check(np.radians([-8.0, 8.0])).spread_deg == pytest.approx(8.0, abs=1e-6)


# --- simulated roads and the GeoPackage -------------------------------------------------------------
def test_simulated_roads_fit_their_lines_through_the_true_scene(sim):
    scene, dem, result = sim
    ground, image = read_ground_lines(result.lines), read_image_lines(result.lines)
    clicks = read_image_lines(result.lines, layer="image_clicks")
    assert len(ground) == 12 and np.all(np.isin(image.line_id, ground.id))
    assert np.allclose(clicks.sigma_px, 2.0) and np.allclose(image.sigma_px, 0.5)
    obs, seg = pair(image, ground), LineSegments.from_lines(ground)
    c = line_constraints(seg, obs.key, start_points(scene, obs, seg))
    # measured: 0.5 px image noise (1.2 m) and 1 m map noise across
    assert 1.0 < np.sqrt(np.mean(c.d_across ** 2)) < 2.0
    assert segment_directions(seg).determined


def test_gpkg_round_trip_keeps_parts_heights_and_vertex_sigmas(tmp_path):
    ground = build_ground_lines(["A", "A", "B"], _parts([(114.0, 34.5, 310.0), (114.01, 34.5, 320.0)],
                                                        [(114.02, 34.5, 330.0), (114.03, 34.5, 335.0)],
                                                        [(114.0, 34.6, 400.0), (114.0, 34.61, 410.0)]),
                                crs="EPSG:4326", heights=Heights("z", "ellipsoid"), sigma_across=[1.0, 1.5, 2.0],
                                sigma_h=3.0)
    image = build_image_lines(["A", "B"], _parts([(10.5, 20.5), (30.5, 40.25), (50, 60)], [(1, 2), (3, 4)]),
                              ["HRC", "HRC"], [np.array([0.1, 0.2, 0.3]), 0.7])
    write_gpkg(tmp_path / "l.gpkg", ground, image)
    g, i = read_ground_lines(tmp_path / "l.gpkg"), read_image_lines(tmp_path / "l.gpkg")
    assert list(g.id) == ["A", "A", "B"] and np.allclose(g.h, ground.h) and np.allclose(g.lon, ground.lon)
    assert np.allclose(g.sigma_across, [1.0, 1.5, 2.0])
    assert np.allclose(i.col, image.col) and np.allclose(i.row, image.row)
    assert np.allclose(i.sigma_px, [0.1, 0.2, 0.3, 0.7, 0.7])
    # a layer in another frame than (col, -row) is refused
    write_gpkg(tmp_path / "flipped.gpkg", image=ImageLines(["A"], "HRC", [0, 2], [1.0, 2.0], [-5.0, -6.0], 1.0))
    with pytest.raises(InputError, match="have y > 0"):
        read_image_lines(tmp_path / "flipped.gpkg")


def test_enu_helper_matches():  # the local frame used by the tests above is the core's
    assert np.allclose(enu_rotation(LON0, LAT0)[2], up_vector(LON0, LAT0))
