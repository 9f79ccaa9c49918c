"""The fuzz leftovers of issue 22, each a clean refusal naming the parameter or file, through
processing.run (stderr captured: no traceback, nothing through Python's 'Exception ignored' hook)
and qgis_process (no traceback on either stream):

* sigmas that overflow or vanish in the normal equations: INTERIOR=HRC.f=1e-300 (a LinAlgError
  once), HRC.f=1e300, POSITION_SIGMA=1e-300, ATTITUDE_SIGMA beyond any star tracker, per-point image
  sigmas of 1e-300;
* simulatescene's error magnitudes beyond any onboard error (POSITION_BIAS=1e308 was accepted);
* a raw image with an RPC given as DEM (reported as a DEM not covering the scene once);
* RPC offsets beyond the Earth (LAT_OFF=1e300 was accepted) in an RPC text, a DIMAP RFM and a
  Maxar RPB.

The full disk and the deeply nested scene JSON are in test_hostile_outputs.py and
test_hostile_scene_json.py.
"""
from __future__ import annotations

import re

import pytest
from osgeo import gdal

import processing
from tests.support.csvrows import read_rows, write_rows
from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.rpcdata import pleiades_rpc, rpc_files, scaled

gdal.UseExceptions()


@pytest.fixture(scope="module")
def block(provider, simulated, tmp_path_factory) -> dict:
    """The simulated CBERS-02B scene's GCPs imported (as they are: id, role, camera read by name), and
    the same with image sigmas of 1e-300 px."""
    folder = tmp_path_factory.mktemp("fuzz_block")
    rows = read_rows(simulated["GCPS"])
    for r in rows:
        r["sigma_px"] = "1e-300"
    tiny = write_rows(folder / "tiny_sigmas.csv", rows)
    common = {"SCENE": simulated["ONBOARD_SCENE"], "Z_FIELD": "h", "Z_DATUM": "ellipsoid"}
    processing.run("pushbroom:importgcps", {**common, "INPUT_FILE": simulated["GCPS"],
                                            "OUTPUT": str(folder / "gcps.gpkg")})
    processing.run("pushbroom:importgcps", {**common, "INPUT_FILE": str(tiny), "SIGMA_PX_FIELD": "sigma_px",
                                            "OUTPUT": str(folder / "tiny.gpkg")})
    return {"scene": simulated["ONBOARD_SCENE"], "gcps": str(folder / "gcps.gpkg"), "tiny": str(folder / "tiny.gpkg")}


def _adjust(block, tmp_path, **kw) -> dict:
    return {"SCENE": block["scene"], "GCPS": block["gcps"], "POSITION_ORDER": 0,
            "OUTPUT_SCENE": str(tmp_path / "adjusted.json"), **kw}


SIGMAS = [
    ("interior sigma 1e-300", {"INTERIOR": "HRC.f=1e-300"},
     ["INTERIOR", "a sigma this small holds HRC.f fixed", "a plausible sigma moves the image by 1e-06 to 1e+06 px"]),
    ("interior sigma 1e300", {"INTERIOR": "HRC.f=1e300"},
     ["INTERIOR", "a sigma this large weighs nothing", "1e-06 to 1e+06 px"]),
    ("interior sigma 1e-9 px", {"INTERIOR": "HRC-1.dx=1e-9px"}, ["INTERIOR", "HRC-1.dx fixed"]),
    ("position sigma 1e-300", {"POSITION_SIGMA": 1e-300}, ["POSITION_SIGMA", "between 0.0001 and 1e+06 m"]),
    ("attitude sigma 1e-9 arcsec", {"ATTITUDE_SIGMA": 1e-9}, ["ATTITUDE_SIGMA", "0.0001 to 36000 arcsec"]),
    ("attitude sigma beyond any star tracker", {"ATTITUDE_SIGMA": 1e9}, ["ATTITUDE_SIGMA"]),
]


@pytest.mark.parametrize("case, extra, texts", SIGMAS, ids=[c[0] for c in SIGMAS])
def test_sigmas_that_overflow_the_normal_equations(block, tmp_path, capfd, case, extra, texts):
    assert_refused("pushbroom:bundleadjust", _adjust(block, tmp_path, **extra), *texts, watch=[tmp_path],
                   capfd=capfd)


def test_per_point_image_sigmas_of_1e_300(block, tmp_path, capfd):
    """Imported (positive, below the largest sigma), they overflowed the normal equations into a
    LinAlgError in the determinability check (later into inf weights caught there); now refused
    before anything is computed, the GCPs and the field named."""
    assert_refused("pushbroom:bundleadjust", _adjust(block, tmp_path, GCPS=block["tiny"]),
                   "sigma_px below 0.0001 px", "no measurement is that precise", watch=[tmp_path],
                   capfd=capfd)


def test_interior_sigma_1e_300_from_the_command_line(qgis_process, block, tmp_path):
    assert_refused_cli(qgis_process, "pushbroom:bundleadjust", _adjust(block, tmp_path, INTERIOR="HRC.f=1e-300"),
                       "INTERIOR", "a sigma this small holds HRC.f fixed", watch=[tmp_path])


# --- simulatescene: error magnitudes ---------------------------------------------------------------
@pytest.mark.parametrize("name, value", [("POSITION_BIAS", 1e308), ("ATTITUDE_BIAS", 1e9), ("CCD_SHIFT", 1e12)])
def test_error_magnitudes_beyond_any_onboard_error_from_the_command_line(qgis_process, tmp_path, name, value):
    assert_refused_cli(qgis_process, "pushbroom:simulatescene", {name: value, "OUTPUT_FOLDER": tmp_path / "sim"},
                       name, watch=[tmp_path])


# --- a raw image with an RPC as DEM ----------------------------------------------------------------
@pytest.fixture(scope="module")
def rpc_image(shared_data, tmp_path_factory):
    """Another scene's raw image with its RPC (Pleiades, as GDAL reads it: RPC tags, no geotransform)."""
    return rpc_files(tmp_path_factory.mktemp("fuzz_rpc"), scaled(pleiades_rpc(shared_data), 16.0), name="other")


def test_a_raw_image_with_an_rpc_as_dem(provider, simulated, rpc_image, tmp_path, capfd):
    assert_refused("pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "DEM": str(rpc_image["tif"]),
                                           "DEM_DATUM": "geoid", "OUTPUT": str(tmp_path / "fp.gpkg")},
                   "other.tif", "a raw image with an RPC (no map georeferencing), not a DEM", watch=[tmp_path],
                   capfd=capfd)


def test_a_raw_image_with_an_rpc_as_dem_from_the_command_line(qgis_process, simulated, rpc_image, tmp_path):
    assert_refused_cli(qgis_process, "pushbroom:footprint",
                       {"SCENE": simulated["TRUE_SCENE"], "DEM": rpc_image["tif"], "DEM_DATUM": "geoid",
                        "OUTPUT": tmp_path / "fp.gpkg"}, "other.tif", "not a DEM", watch=[tmp_path])


# --- RPC offsets beyond the Earth --------------------------------------------------------------------
def _rpc_text(rpc_image, tmp_path, key: str, value: str):
    path = tmp_path / "in" / "bad_RPC.TXT"
    path.parent.mkdir()
    path.write_text("\n".join(f"{key}: {value}" if line.startswith(key + ":") else line
                              for line in rpc_image["txt"].read_text().splitlines()))
    return path


@pytest.mark.parametrize("key, value, expected", [
    ("LAT_OFF", "1e300", "a plausible value lies between -90 and 90"),
    ("LONG_OFF", "-720", "a plausible value lies between -180 and 360"),
    ("HEIGHT_OFF", "1e7", "a plausible value lies between -12000 and 100000"),
    ("LAT_SCALE", "1e300", "a plausible |scale| lies between 0 and 90"),
    ("SAMP_SCALE", "1e20", "a plausible |scale| lies between 0 and 1e+08"),
])
def test_rpc_offsets_and_scales_beyond_the_earth(provider, rpc_image, tmp_path, capfd, key, value, expected):
    path = _rpc_text(rpc_image, tmp_path, key, value)
    assert_refused("pushbroom:footprint", {"SCENE": str(path), "HEIGHT": 575.0, "OUTPUT": str(tmp_path / "fp.gpkg")},
                   "SCENE", "bad_RPC.TXT", key, expected, watch=[tmp_path], capfd=capfd)


def test_lat_off_1e300_from_the_command_line(qgis_process, rpc_image, tmp_path):
    path = _rpc_text(rpc_image, tmp_path, "LAT_OFF", "1e300")
    assert_refused_cli(qgis_process, "pushbroom:footprint", {"SCENE": path, "HEIGHT": 575.0,
                                                             "OUTPUT": tmp_path / "fp.gpkg"},
                       "bad_RPC.TXT", "LAT_OFF", "between -90 and 90", watch=[tmp_path])


def test_a_dimap_rfm_latitude_offset_beyond_the_poles(provider, shared_data, tmp_path, capfd):
    """The Pleiades DIMAP's Global_RFM (read with the sensor model: its height range) with
    RFM_Validity/Lat/B = 1e300."""
    source = shared_data / "pleiades" / "PHRDIMAP_P1BP--2018122638935449CP.XML"
    text = source.read_text()
    lat = re.search(r"<Lat>.*?</Lat>", text, flags=re.S)
    assert lat, "the DIMAP holds RFM_Validity/Lat"
    edited = text[:lat.start()] + re.sub(r"<B>[^<]*</B>", "<B>1e300</B>", lat.group(0)) + text[lat.end():]
    path = tmp_path / "in" / source.name
    path.parent.mkdir()
    path.write_text(edited)
    assert_refused("pushbroom:footprint", {"SCENE": str(path), "HEIGHT": 500.0, "OUTPUT": str(tmp_path / "fp.gpkg")},
                   source.name, "RFM_Validity/Lat/B", "between -90 and 90", watch=[tmp_path], capfd=capfd)


def test_a_maxar_rpb_latitude_offset_beyond_the_poles(provider, shared_data, tmp_path, capfd):
    """The WorldView-2 XML's RPB with LATOFFSET = 1e300."""
    text = (shared_data / "worldview2" / "wv_mvp_1.xml").read_text()
    assert "<LATOFFSET>" in text
    path = tmp_path / "in" / "scene.xml"
    path.parent.mkdir()
    path.write_text(re.sub(r"<LATOFFSET>[^<]*</LATOFFSET>", "<LATOFFSET>1e300</LATOFFSET>", text, count=1))
    assert_refused("pushbroom:footprint", {"SCENE": str(path), "HEIGHT": 0.0, "OUTPUT": str(tmp_path / "fp.gpkg")},
                   "scene.xml", "RPB/IMAGE/LATOFFSET", "between -90 and 90", watch=[tmp_path], capfd=capfd)
