"""Hostile inputs to the robust adjustment: per-point sigma fields that are zero, negative, NaN,
text or missing (refused at import, naming the field and the points, nothing written), and
legitimate but hard data (half of the points gross, a CCD half shifted, a pass limit hit,
surveyed and digitised points mixed) that must give a result that says what is wrong."""
import json
from pathlib import Path

import numpy as np
import pytest

import processing
from pushbroom_adjust.core.observations.gcps import read_gpkg

from tests.support.csvrows import read_rows, write_rows
from tests.support.hostile import assert_refused, assert_unchanged, snapshot
from tests.support.processing import RecordingFeedback

INTERIOR = "HRC-1.*, HRC-3.*"


class _Log(RecordingFeedback):
    """Keeps the info lines too."""
    info: list

    def pushInfo(self, info):  # noqa: N802 (QGIS API name)
        self.__dict__.setdefault("info", []).append(info)


@pytest.fixture(scope="module")
def sims(provider, tmp_path_factory) -> dict:
    """Two simulated CBERS-02B scenes of 500 points (a third check points, 0.5 px and 1 m noise):
    without gross errors, and with half of the measurements gross."""
    out = tmp_path_factory.mktemp("hostile_adjust")
    return {gross: processing.run("pushbroom:simulatescene", {
        "SEED": 8, "N_GCPS": 500, "IMAGE_NOISE": 0.5, "CHECK_FRACTION": 0.3, "GROSS_FRACTION": gross,
        "GROUND_NOISE_XY": 1.0, "GROUND_NOISE_Z": 1.0, "OUTPUT_FOLDER": str(out / f"sim{gross}")})
        for gross in (0.0, 0.5)}


def _import_params(sim, path: Path, output: Path, **extra) -> dict:
    return {"SCENE": sim["ONBOARD_SCENE"], "INPUT_FILE": str(path), "Z_FIELD": "h", "Z_DATUM": "ellipsoid",
            "ROLE_FIELD": "role", "CAMERA_FIELD": "camera", "OUTPUT": str(output), **extra}


# --- per-point sigma fields refused at import ------------------------------------------------------
@pytest.mark.parametrize("field, values, expected", [
    ("sigma_px", lambda i: "0", "'sigma_px' must hold numbers > 0"),          # all image sigmas zero
    ("sigma_xy", lambda i: "-1", "'sigma_xy' must hold numbers > 0"),         # all ground sigmas negative
    ("sigma_z", lambda i: "nan" if i % 7 == 0 else "2", "G1: 'nan'"),          # some NaN, named
    ("sigma_px", lambda i: "0.5 px" if i == 3 else "0.5", "'0.5 px'"),         # a unit in the cell
    ("sigma_xy", lambda i: "1e308", "below 100000"),                             # beyond any measurement
])
def test_bad_per_point_sigmas_are_refused_at_import(sims, tmp_path, field, values, expected):
    sim = sims[0.0]
    rows = read_rows(sim["GCPS"])
    for i, r in enumerate(rows):
        r[field] = values(i)
    path = write_rows(tmp_path / "gcps.csv", rows)
    param = {"sigma_px": "SIGMA_PX_FIELD", "sigma_xy": "SIGMA_XY_FIELD", "sigma_z": "SIGMA_Z_FIELD"}[field]
    assert_refused("pushbroom:importgcps", _import_params(sim, path, tmp_path / "out.gpkg", **{param: field}),
                   str(path), "per-point sigma field", expected, watch=[tmp_path])


def test_a_sigma_field_the_file_does_not_have_is_named(sims, tmp_path):
    sim = sims[0.0]
    path = write_rows(tmp_path / "gcps.csv", read_rows(sim["GCPS"]))
    assert_refused("pushbroom:importgcps", _import_params(sim, path, tmp_path / "out.gpkg",
                                                          SIGMA_Z_FIELD="sz"),
                   "no column 'sz'", "sigma_z", watch=[tmp_path])


# --- hard but legitimate data: a result that says what is wrong ---------------------------------------
def _gcps(sim, folder: Path, rows: list[dict] | None = None, **extra) -> str:
    path = write_rows(folder / "gcps.csv", rows) if rows else Path(sim["GCPS"])
    return processing.run("pushbroom:importgcps", _import_params(sim, path, folder / "gcps.gpkg",
                                                                 SIGMA_PX=0.5, **extra))["OUTPUT"]


def _adjust(sim, gcps: str, folder: Path, **extra) -> tuple[dict, _Log]:
    log = _Log()
    result = processing.run("pushbroom:bundleadjust", {
        "SCENE": sim["ONBOARD_SCENE"], "GCPS": gcps, "INTERIOR": INTERIOR,
        "OUTPUT_SCENE": str(folder / "adjusted.json"), "OUTPUT_REPORT": str(folder / "report.html"),
        "OUTPUT_GCPS": str(folder / "adjusted_gcps.gpkg"), "OUTPUT_RESIDUALS": str(folder / "residuals.gpkg"),
        **extra}, feedback=log)
    return json.loads(Path(result["OUTPUT_REPORT_JSON"]).read_text()), log


def test_half_of_the_points_gross_is_not_reported_as_a_good_result(sims, tmp_path):
    sim = sims[0.5]
    before = snapshot(sim["GCPS"], sim["ONBOARD_SCENE"])
    rep, log = _adjust(sim, _gcps(sim, tmp_path), tmp_path)
    assert not rep["reliability"]["reliable"]
    assert any("flagged as gross errors" in w and "the result is not reliable" in w for w in log.warnings)
    assert "The result is not reliable" in (tmp_path / "report.html").read_text()
    assert json.loads((tmp_path / "adjusted.json").read_text())["info"]["adjustment"]["reliable"] is False
    assert_unchanged(before, [sim["GCPS"], sim["ONBOARD_SCENE"]])


def test_half_of_one_ccd_shifted_the_same_way_names_the_ccd(sims, tmp_path):
    """Half of HRC-3's points moved 20 px the same way: the robust weights flag the whole chip;
    the log names HRC-3 and calls the result not reliable."""
    sim = sims[0.0]
    rows = read_rows(sim["GCPS"])
    cols = np.array([float(r["col"]) for r in rows])
    third = cols > 2 * cols.max() / 3
    for i in np.nonzero(third)[0][::2]:
        rows[i]["col"], rows[i]["row"] = str(float(rows[i]["col"]) + 20), str(float(rows[i]["row"]) + 20)
    rep, log = _adjust(sim, _gcps(sim, tmp_path, rows), tmp_path)
    assert not rep["reliability"]["reliable"]
    assert any(w.startswith("HRC/HRC-3:") and "not reliable" in w for w in log.warnings), log.warnings
    assert not any(w.startswith(("HRC/HRC-1:", "HRC/HRC-2:")) for w in log.warnings)


def test_a_run_at_its_pass_limit_says_so(sims, tmp_path):
    sim = sims[0.5]
    rep, log = _adjust(sim, _gcps(sim, tmp_path), tmp_path, MAX_ROBUST_PASSES=1)
    assert rep["robust"]["stopped_at_limit"]
    assert "robust estimation stopped at its limit of 1 passes; the flags may be incomplete" in log.warnings
    assert "robust estimation stopped at its limit of 1 passes; the flags may be incomplete" in rep["warnings"]
    assert "stopped at its limit of 1 passes" in (tmp_path / "report.html").read_text()


def test_surveyed_and_digitised_points_mixed_by_per_point_sigmas(sims, tmp_path):
    """Half of the points surveyed (0.2 m), half digitised from a map (5 m), each measured that
    well and saying so; one cell left empty (the default, 3 m): they reach the GCP layer and the
    adjustment, which converges, keeps the good points and logs the components."""
    sim = sims[0.0]
    rows = read_rows(sim["GCPS"])
    rng = np.random.default_rng(3)
    for i, r in enumerate(rows):
        sigma = 3.0 if i == 0 else (0.2 if i % 2 else 5.0)
        r["sxy"] = "" if i == 0 else str(sigma)
        east, north = rng.normal(0.0, sigma, 2)
        lat = float(r["lat_true"])
        r["lat"] = str(lat + north / 111_320.0)
        r["lon"] = str(float(r["lon_true"]) + east / (111_320.0 * np.cos(np.radians(lat))))
    gcps = _gcps(sim, tmp_path, rows, SIGMA_XY_FIELD="sxy", SIGMA_XY=3.0)
    table = read_gpkg(gcps)
    by_id = {r["id"]: r["sxy"] for r in rows}
    expected = np.array([float(by_id[i] or 3.0) for i in table.id])
    assert np.array_equal(table.sigma_xy, expected)
    rep, log = _adjust(sim, gcps, tmp_path)
    assert rep["reliability"]["reliable"] and not rep["robust"]["stopped_at_limit"]
    assert rep["robust"]["flagged"] <= 0.01 * rep["observations"]["image_observations"]
    assert rep["variance_components"]["image HRC"]["estimated_sigma"] == pytest.approx(0.5, rel=0.15)
    assert any(w.startswith("variance component image HRC: stated sigma 0.5 px, estimated") for w in log.info)


def test_a_prior_that_holds_a_parameter_fixed_is_refused_naming_interior(sims, tmp_path):
    """INTERIOR=HRC.f=1e-300 overflowed the normal equations (a LinAlgError traceback): now INTERIOR is
    named."""
    sim = sims[0.0]
    gcps = _gcps(sim, tmp_path)
    params = {"SCENE": sim["ONBOARD_SCENE"], "GCPS": gcps, "INTERIOR": "HRC.f=1e-300",
              "OUTPUT_SCENE": str(tmp_path / "adjusted.json")}
    assert_refused("pushbroom:bundleadjust", params, "INTERIOR", "a sigma this small holds HRC.f fixed",
                   watch=[tmp_path])
