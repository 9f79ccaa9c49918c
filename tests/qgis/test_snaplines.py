"""Simulated roads through pushbroom:simulatescene (N_LINES) read by importlines, and
pushbroom:snaplines refining clicks with 2 px error to a rendered road (issue 11, done-when 3)."""
from __future__ import annotations

import numpy as np
from osgeo import ogr

from pushbroom_adjust.core.observations.lines import read_image_lines, write_gpkg
from tests.support.snapping import across_error, clicks_along


def test_simulatescene_with_n_lines_writes_roads_importlines_reads(provider, tmp_path):
    import processing
    sim = processing.run("pushbroom:simulatescene", {
        "PRESET": "cbers02b_hrc", "SEED": 5, "N_GCPS": 10, "N_LINES": 12, "WRONG_LINE_FRACTION": 0.25,
        "OUTPUT_FOLDER": str(tmp_path / "sim")})
    assert sim["LINES"] == str(tmp_path / "sim" / "lines.gpkg")
    ds = ogr.Open(sim["LINES"])
    ground = ds.GetLayer("ground_lines")
    kinds = [f.GetField("kind") for f in ground]
    assert len(kinds) == 12 and sum(k != "correct" for k in kinds) == 3   # 25 % of 12 wrong
    assert ds.GetLayer("image_clicks").GetFeatureCount() == ds.GetLayer("image_lines").GetFeatureCount() >= 12
    assert (tmp_path / "sim" / "line_points.csv").is_file()
    out = tmp_path / "control_lines.gpkg"
    processing.run("pushbroom:importlines", {
        "SCENE": sim["ONBOARD_SCENE"], "INPUT": f"{sim['LINES']}|layername=ground_lines",
        "IMAGE_LINES": f"{sim['LINES']}|layername=image_lines", "HEIGHT_SOURCE": "z", "Z_DATUM": "ellipsoid",
        "OUTPUT": str(out)})
    assert ogr.Open(str(out)).GetLayer("ground_lines").GetFeatureCount() == 12


def test_simulatescene_without_n_lines_writes_no_roads(simulated):
    assert simulated["LINES"] is None


def test_snaplines_refines_clicks_to_0_3px_across_the_rendered_road(provider, rendered, tmp_path):
    import processing
    path, scene, truth = rendered
    clicks = clicks_along(truth, 40.0, 2.0, np.random.default_rng(1), scene.cameras[0].cols)
    write_gpkg(tmp_path / "clicks.gpkg", image=clicks)
    out = tmp_path / "snapped.gpkg"
    processing.run("pushbroom:snaplines", {"INPUT": str(path), "IMAGE_LINES": str(tmp_path / "clicks.gpkg"),
                                           "MODE": "centre", "WIDTH": 3.0, "SEARCH": 10.0, "OUTPUT": str(out)})
    snapped = read_image_lines(out)
    refined = snapped.sigma_px != 2.0          # kept vertices keep the clicks' sigma
    before, after = across_error(clicks, truth), across_error(snapped, truth)
    rms_before, rms_after = np.sqrt(np.mean(before ** 2)), np.sqrt(np.mean(after[refined] ** 2))
    print(f"snaplines: {before.size} clicks, RMS across {rms_before:.2f} px -> {rms_after:.3f} px, "
          f"refined {refined.sum()}")
    assert rms_before > 1.0 and refined.mean() >= 0.95 and rms_after <= 0.3
    assert np.all((snapped.sigma_px[refined] >= 0.1) & (snapped.sigma_px[refined] < 0.5))
    assert list(snapped.line_id) == list(clicks.line_id)
    ds = ogr.Open(str(out))
    counts = [f.GetField("refined") for f in ds.GetLayer("image_lines")]
    assert sum(counts) == refined.sum()
