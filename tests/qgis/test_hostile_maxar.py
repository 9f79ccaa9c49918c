"""Hostile inputs: Maxar/DigitalGlobe isd XML (WorldView) through pushbroom:footprint and
pushbroom:groundtoimage.

Each case edits a temporary copy of a real WorldView-2 XML (tests/data/worldview2, via the
``shared_data`` fixture) and asserts the exact behaviour: a QgsProcessingException naming SCENE,
the file and the field, with the XML and the output folder unchanged; or, for input that is
legitimate but not what the reader was checked on, a result with a warning naming what it assumed.
"""
from __future__ import annotations

import json
import re

import pytest

import processing

from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback

SOURCE = "wv_mvp_1.xml"


def _edited(shared_data, tmp_path, edit):
    """A copy of the WorldView-2 XML with ``edit`` (text -> text) applied, and an empty output folder."""
    path = tmp_path / "scene.xml"
    path.write_text(edit((shared_data / "worldview2" / SOURCE).read_text()))
    out = tmp_path / "out"
    out.mkdir()
    return path, out


def _ground_points(tmp_path, lon, lat, h):
    """A GeoJSON file with one 3D point (WGS84, ellipsoidal height)."""
    path = tmp_path / "points.geojson"
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "p"},
         "geometry": {"type": "Point", "coordinates": [lon, lat, h]}}]}))
    return path


REFUSED = {
    "no EPH block": (lambda t: re.sub(r"<EPH>.*</EPH>", "", t, flags=re.S),
                     [r"<EPH> section (ephemeris) is missing"]),
    "no ATT block": (lambda t: re.sub(r"<ATT>.*</ATT>", "", t, flags=re.S),
                     [r"<ATT> section (attitude) is missing"]),
    "no GEO block": (lambda t: re.sub(r"<GEO>.*</GEO>", "", t, flags=re.S),
                     [r"<GEO> section (camera geometry) is missing"]),
    "principal distance not a number": (lambda t: re.sub(r"<PD>[^<]*</PD>", "<PD>sixteen metres</PD>", t),
                                        ["GEO/PRINCIPAL_DISTANCE/PD", "'sixteen metres' is not a number"]),
    "truncated XML": (lambda t: t[:len(t) * 2 // 3], ["not well-formed XML, truncated"]),
    "map-projected product (ORStandard2A)": (
        lambda t: t.replace("<IMAGEDESCRIPTOR>Stereo1B", "<IMAGEDESCRIPTOR>ORStandard2A"),
        ["IMD/IMAGEDESCRIPTOR is 'ORStandard2A'", "not a Basic1B or Stereo1B product"]),
    "attitude sample NaN": (lambda t: re.sub(r"(<ATTLIST>\S+) \S+", r"\1 NaN", t, count=1),
                            ["ATT/ATTLISTList/ATTLIST", "finite numbers"]),
    "ephemeris interval zero": (
        lambda t: re.sub(r"(<EPH>.*?<TIMEINTERVAL>)[^<]*", r"\g<1>0.0", t, count=1, flags=re.S),
        ["EPH/TIMEINTERVAL must be positive"]),
    "image width zero": (lambda t: t.replace("<NUMCOLUMNS>32837<", "<NUMCOLUMNS>0<"),
                         ["IMD/NUMCOLUMNS is 0", "whole number of pixels"]),
    "image height fractional": (lambda t: t.replace("<NUMROWS>27968<", "<NUMROWS>27968.5<"),
                                ["IMD/NUMROWS is 27968.5", "whole number of pixels"]),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_broken_maxar_xml_is_refused_by_footprint(provider, shared_data, tmp_path, case):
    edit, texts = REFUSED[case]
    path, out = _edited(shared_data, tmp_path, edit)
    assert_refused("pushbroom:footprint", {"SCENE": str(path), "HEIGHT": 600.0, "OUTPUT": str(out / "fp.gpkg")},
                   "SCENE:", str(path), *texts, watch=[path, out])


def test_broken_maxar_xml_is_refused_by_groundtoimage(provider, shared_data, tmp_path):
    path, out = _edited(shared_data, tmp_path, lambda t: t.replace("<FIRSTLINETIME>2014-06-19",
                                                                   "<FIRSTLINETIME>19/06/2014"))
    points = _ground_points(tmp_path, -117.6, 35.3, 700.0)
    assert_refused("pushbroom:groundtoimage", {"SCENE": str(path), "INPUT": str(points),
                                               "OUTPUT": str(out / "points.gpkg")},
                   "SCENE:", "IMD/IMAGE/FIRSTLINETIME", "is not a UTC time", watch=[path, points, out])


def test_broken_maxar_xml_is_refused_on_the_command_line(qgis_process, shared_data, tmp_path):
    path, out = _edited(shared_data, tmp_path, lambda t: re.sub(r"<ATT>.*</ATT>", "", t, flags=re.S))
    assert_refused_cli(qgis_process, "pushbroom:footprint",
                       {"SCENE": path, "HEIGHT": 600, "OUTPUT": out / "fp.gpkg"},
                       "<ATT> section (attitude) is missing", watch=[path, out])


@pytest.mark.parametrize("edit, unknown", [
    (lambda t: t.replace("<VERSION>24.06</VERSION>", "<VERSION>29.1</VERSION>", 1),
     "ISD version 29.1 is newer than the newest checked (28.x)"),
    (lambda t: t.replace("<SATID>WV02</SATID>", "<SATID>LG03</SATID>", 1), "satellite IMD/IMAGE/SATID 'LG03'"),
])
def test_unplaced_maxar_generation_gives_a_footprint_and_a_warning(provider, shared_data, tmp_path, edit, unknown):
    """Legitimate but unplaced: the footprint is made (the same as the original's, as the
    convention assumed is the same) and the log says what was assumed."""
    path, out = _edited(shared_data, tmp_path, edit)
    feedback = RecordingFeedback()
    result = processing.run("pushbroom:footprint", {"SCENE": str(path), "HEIGHT": 600.0, "OUTPUT": "memory:"},
                            feedback=feedback)
    original = processing.run("pushbroom:footprint", {"SCENE": str(shared_data / "worldview2" / SOURCE),
                                                      "HEIGHT": 600.0, "OUTPUT": "memory:"})
    (warning,) = [w for w in feedback.warnings if "cannot place" in w]
    assert warning.startswith("SCENE: ") and str(path) in warning and unknown in warning
    assert "velocity aberration and atmospheric refraction applied" in warning
    (fp,), (ref,) = result["OUTPUT"].getFeatures(), original["OUTPUT"].getFeatures()
    assert fp["area_km2"] == pytest.approx(ref["area_km2"], rel=1e-9) and fp["cols"] == 32837


def test_rpb_refitted_by_asp_is_warned(provider, shared_data, tmp_path):
    """The real WorldView-3 file (joined by the Ames Stereo Pipeline's dg_mosaic): its RPB is not
    Maxar's, so ground -> image runs and the log says why it differs from the RPB by ~15 m."""
    xml = shared_data / "worldview3" / "1040010074793300.xml"
    points = _ground_points(tmp_path, -156.6250, 71.3315, 7.0)
    feedback = RecordingFeedback()
    out = processing.run("pushbroom:groundtoimage", {"SCENE": str(xml), "INPUT": str(points), "OUTPUT": "memory:"},
                         feedback=feedback)["OUTPUT"]
    (warning,) = [w for w in feedback.warnings if "RPB" in w]
    assert "Ames Stereo Pipeline" in warning and "not made by Maxar" in warning and "~15 m" in warning
    (f,) = out.getFeatures()
    assert f["in_image"] == 1 and 0 < f["col"] < 43008 and 0 < f["row"] < 38912
