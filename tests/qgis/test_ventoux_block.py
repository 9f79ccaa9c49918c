"""The real Ventoux crops (tests/data/pleiades_ventoux: a Pleiades 1B stereo pair whose RPCs keep the full
products' offsets) through qgis_process as a user runs it: matchtiepoints with SCENES (the images themselves,
GDAL reading their _RPC.TXT) on the SRTM window with NaN holes, then bundleadjust with SCENES and the ties alone;
the adjusted scenes judged by the independent triangulation check of tests/support/independent_match.py (issue
28, done-when 1), and again with the SRTM window as the reference DEM of the tie heights (issue 31; a DEM
without TIE_HEIGHT_SIGMA, the sigma without a DEM and a DEM beside the block refused, naming the parameter).
The input files (copied into a folder of their own) stay byte-identical.

Measured (SPACING 56, so that check points 35 px from every tie remain; SEARCH_RANGE, WINDOW and FINE_RADIUS at
their defaults, 1000 m clipped to the crop, 31 px, 8 px): the 14 grid points in the two crops' overlap all tied
(50 outside the right image), tie RMS 2.425 -> 0.056 px with RPC_CORRECTION shift and RPC_SIGMA 10 px; 113 check
points at least 35 px from every tie: 2.423 px through the vendor RPCs, 0.062 px through the adjusted scenes.
Before (issue 28's matcher) the right crop had to come first with SEARCH_RANGE 10 m, its least value: 11 ties of
14, 2.446 -> 0.078 px; 167 check points, 2.407 -> 0.065 px.
Not asserted here: a srtm_big_hole.tif.aux.xml appears beside the DEM given (issue 28, item 10: another part of
the issue).
"""
import json
import logging
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.observations import tiepoints
from tests.support.hostile import assert_refused, assert_unchanged, snapshot
from tests.support.independent_match import triangulation_check
from tests.support.qgis_process import run_json

log = logging.getLogger(__name__)
NAMES = ("left_image", "right_image")
FILES = ("left_image.tif", "left_image_RPC.TXT", "right_image.tif", "right_image_RPC.TXT", "srtm_big_hole.tif")


@pytest.fixture(scope="module")
def run(shared_data, qgis_process, tmp_path_factory) -> dict:
    """matchtiepoints then bundleadjust through qgis_process on a copy of the Ventoux crops; the inputs' state
    before, the tie layer, the block report and the adjusted scenes."""
    inputs = tmp_path_factory.mktemp("ventoux_inputs")
    for name in FILES:
        (inputs / name).write_bytes((shared_data / "pleiades_ventoux" / name).read_bytes())
    before = snapshot(*(inputs / name for name in FILES))
    images = [str(inputs / f"{n}.tif") for n in NAMES]
    out = tmp_path_factory.mktemp("ventoux_out")
    ties = run_json(qgis_process, "pushbroom:matchtiepoints", SCENES=images, INPUTS=images,
                    DEM=str(inputs / "srtm_big_hole.tif"), DEM_DATUM="geoid", SPACING=56, OUTPUT=str(out / "ties.gpkg"))["OUTPUT"]
    adjusted = run_json(qgis_process, "pushbroom:bundleadjust", SCENES=images, TIE_POINTS=ties,
                        RPC_CORRECTION="shift", RPC_SIGMA=10, OUTPUT_FOLDER=str(out / "block"))
    report = json.loads((out / "block" / "block_report.json").read_text())
    return {"inputs": inputs, "before": before, "images": images, "ties": tiepoints.read_gpkg(ties),
            "report": report, "adjusted": adjusted["ADJUSTED_SCENES"]}


def test_the_crops_are_tied_and_adjusted_from_the_command_line(run):
    table = run["ties"]
    n = int((table.scene == NAMES[1]).sum())
    log.info("Ventoux through qgis_process: %d ties, block %s", n, run["report"]["block"])
    assert set(table.scene) == set(NAMES) and n >= 13, n                # measured 14
    block = run["report"]["block"]
    assert 2.0 < block["tie_rmse_before_px"] < 2.9 and block["tie_rmse_px"] < 0.1, block   # measured 2.425, 0.056
    assert_unchanged(run["before"], [run["inputs"] / name for name in FILES])


def test_the_adjusted_crops_pass_the_independent_triangulation_check(run):
    table = run["ties"]
    left = table.scene == NAMES[0]
    vendor = tuple(load_scene(p) for p in run["images"])
    adjusted = {Path(p).name: load_scene(p) for p in run["adjusted"]}
    check = triangulation_check({"vendor": vendor, "adjusted": tuple(adjusted[f"{n}_adjusted.json"] for n in NAMES)},
                                tuple(run["images"]), np.stack([table.col[left], table.row[left]], axis=1),
                                Dem(run["inputs"] / "srtm_big_hole.tif", datum="geoid"), step=8.0)
    log.info("Ventoux through qgis_process: %d check points, RMS %s", len(check.points.a), check.rms)
    assert len(check.points.a) >= 80                                     # measured 113
    assert 2.0 < check.rms["vendor"] < 2.9                                # measured 2.423 px
    assert check.rms["adjusted"] <= 0.1, check.rms                        # measured 0.062 px



def test_the_srtm_window_holds_the_tie_heights_and_its_hole_is_counted(run, qgis_process, tmp_path):
    """DEM (the SRTM window, EGM96 heights) with TIE_HEIGHT_SIGMA holds the pair's tie heights, which with
    RPC_CORRECTION shift and no GCP only RPC_SIGMA holds otherwise (issue 31); the report counts the ties.
    Measured: 14 ties held (none on the hole), the height shift held to 1.3 m (the priors' 20.2 m alone), the
    block moved -3.9 m in height (0.02 m without the DEM), the ties' heights 8.7 m RMS from SRTM's (largest
    13.1 m), tie RMS unchanged."""
    ties = str(tmp_path / "ties.gpkg")
    tiepoints.write_gpkg(run["ties"], ties)
    run_json(qgis_process, "pushbroom:bundleadjust", SCENES=run["images"], TIE_POINTS=ties, RPC_CORRECTION="shift",
             RPC_SIGMA=10, DEM=str(run["inputs"] / "srtm_big_hole.tif"), DEM_DATUM="geoid", TIE_HEIGHT_SIGMA=5,
             OUTPUT_FOLDER=str(tmp_path / "block"))
    report = json.loads((tmp_path / "block" / "block_report.json").read_text())
    heights = report["adjustment"]["tie_points"]["heights"]
    free = {d["direction"]: d for d in run["report"]["datum_directions"]}["height shift"]
    held = {d["direction"]: d for d in report["datum_directions"]}["height shift"]
    log.info("Ventoux with the SRTM window: %s; height shift %s, without the DEM %s", heights, held, free)
    assert heights["constrained"] + heights["off_dem"] + heights["on_holes"] == report["adjustment"]["tie_points"][
        "points"]
    assert free["held_by"] == "priors" and held["held_by"] == "reference DEM"
    assert held["ties_sigma_m"] < 0.1 * free["prior_sigma_m"]                # measured 1.3 m against 20.2 m
    assert abs(free["moved_m"]) < 0.5 and -8.0 < held["moved_m"] < -1.0       # measured 0.02 m, -3.9 m
    assert heights["misfit_rms_m"] < 3 * 5                                    # measured 8.7 m
    assert report["block"]["tie_rmse_px"] < 0.1                               # measured 0.056 px
    page = (tmp_path / "block" / "block_report.html").read_text()
    assert "14 tie points held to the reference DEM " in page and "the reference DEM holds" in page


def test_a_reference_dem_given_wrong_is_refused_naming_the_parameter(run, provider, tmp_path):
    ties = str(tmp_path / "ties.gpkg")
    tiepoints.write_gpkg(run["ties"], ties)
    elsewhere = tmp_path / "elsewhere.tif"
    ds = gdal.GetDriverByName("GTiff").CreateCopy(str(elsewhere), gdal.Open(str(run["inputs"] / "srtm_big_hole.tif")))
    gt = list(ds.GetGeoTransform())
    ds.SetGeoTransform([gt[0] + 3.0, *gt[1:]])
    ds = None
    given = {"SCENES": run["images"], "TIE_POINTS": ties, "RPC_SIGMA": 10, "OUTPUT_FOLDER": str(tmp_path / "out")}
    dem = str(run["inputs"] / "srtm_big_hole.tif")
    for extra, texts in (({"DEM": dem}, ("TIE_HEIGHT_SIGMA: a reference DEM", "needs its stated accuracy")),
                         ({"TIE_HEIGHT_SIGMA": 5}, ("DEM: TIE_HEIGHT_SIGMA holds the tie points' heights",)),
                         ({"DEM": str(elsewhere), "TIE_HEIGHT_SIGMA": 5},
                          ("DEM: the reference DEM", "gives no height at any of the 14 tie points (14 off its extent"))):
        message = assert_refused("pushbroom:bundleadjust", {**given, **extra}, *texts, watch=[run["inputs"]])
        assert "settings." not in message and not (tmp_path / "out").exists()
