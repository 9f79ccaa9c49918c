"""Hostile DIMAP metadata through pushbroom:footprint (harness: hostile.py), variants of the real
Pleiades product (tests/data/pleiades): layouts DIMAP allows give the right footprint; broken or
implausible files are refused with a message naming the file and the element, nothing written."""
from __future__ import annotations

import os
import re

import pytest

import processing
from tests.support.hostile import assert_refused

XML = "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"


def _footprint(scene, out="memory:"):
    return {"SCENE": str(scene), "HEIGHT": 575.0, "OUTPUT": out}


def _area(scene) -> float:
    layer = processing.run("pushbroom:footprint", _footprint(scene))["OUTPUT"]
    (feature,) = list(layer.getFeatures())
    return float(feature["area_km2"])


def _edited(shared_data, folder, edit, name="product.XML"):
    text = (shared_data / XML).read_text()
    path = folder / name
    path.write_text(edit(text))
    return path


def _retina(first, last):
    return lambda t: re.sub(r"<Position_In_Retina>.*?</Position_In_Retina>",
                            f"<Position_In_Retina><FIRST_COL>{first}</FIRST_COL><LAST_COL>{last}</LAST_COL>"
                            "</Position_In_Retina>", t, flags=re.S)


@pytest.fixture(scope="module")
def full_area(provider, shared_data):
    return _area(shared_data / XML)


@pytest.mark.parametrize("first, last", [(1, 40001), (1, 45000)])
def test_retina_wider_than_the_image_gives_the_same_footprint(shared_data, tmp_path, full_area, first, last):
    assert _area(_edited(shared_data, tmp_path, _retina(first, last))) == pytest.approx(full_area, rel=1e-12)


def _rfm_columns_from(first: int):
    """The Global_RFM of a product cut across track from retina column ``first``: its column offset
    moved by the cut (a cut product's RFM is its own; the reader checks the model against it)."""
    return lambda t: re.sub(r"(<Col>\s*<A>[^<]*</A>\s*<B>)[^<]*", rf"\g<1>{20000.5 - (first - 1)!r}", t, count=1)


def test_product_cut_across_track_has_its_share_of_the_footprint(shared_data, tmp_path, full_area):
    """Columns 10001..30000 of the acquisition: half the columns, about half the area."""
    cut = _edited(shared_data, tmp_path, lambda t: _rfm_columns_from(10001)(_retina(10001, 30000)(
        t.replace("<NCOLS>40000</NCOLS>", "<NCOLS>20000</NCOLS>", 1))))
    assert _area(cut) == pytest.approx(full_area / 2, rel=0.02)


def _drop(tag):
    return lambda t: re.sub(rf"<{tag}>.*?</{tag}>", "", t, count=1, flags=re.S)


def _set(tag, value):
    return lambda t: re.sub(rf"<{tag}>[^<]*</{tag}>", f"<{tag}>{value}</{tag}>", t, count=1)


def _duplicate(tag):
    return lambda t: re.sub(rf"(<{tag}>[^<]*</{tag}>)", r"\1\1", t, count=1)


CASES = {
    "retina narrower than the image": (_retina(1, 39000), ("Position_In_Retina", "do not cover")),
    "retina from column 0": (_retina(0, 40000), ("Position_In_Retina",)),
    "retina far outside (look angles)": (_retina(2_000_001, 2_040_000), ("PsiX_Model", "look angles")),
    "look angles in degrees": (lambda t: t.replace("<COEFFICIENTS>-0.01422 7.11e-07</COEFFICIENTS>",
                                                   "<COEFFICIENTS>-0.8147 4.07e-05</COEFFICIENTS>"),
                               ("PsiX_Model", "radians expected")),
    "missing NCOLS": (_drop("NCOLS"), ("NCOLS", "missing")),
    "missing ephemeris": (_drop("Sensor_Ephemeris"), ("Sensor_Ephemeris", "missing")),
    "missing viewing model": (_drop("Sensor_Viewing_Model"), ("Sensor_Viewing_Model", "missing")),
    "duplicated NCOLS": (_duplicate("NCOLS"), ("NCOLS", "appears 2 times")),
    "duplicated line period": (_duplicate("SENSOR_LINE_PERIOD"), ("SENSOR_LINE_PERIOD", "appears 2 times")),
    "non-numeric NROWS": (_set("NROWS", "many"), ("NROWS", "not a finite number")),
    "NaN line period": (_set("SENSOR_LINE_PERIOD", "NaN"), ("SENSOR_LINE_PERIOD", "not a finite number")),
    "line period in seconds": (_set("SENSOR_LINE_PERIOD", "7.35e-05"), ("SENSOR_LINE_PERIOD", "milliseconds")),
    "non-numeric retina column": (_retina("one", 40000), ("FIRST_COL", "not a finite number")),
    "bad UTC time": (lambda t: t.replace("<START>2018-12-26T10:48:55.4490000Z</START>",
                                         "<START>26/12/2018 10:48</START>"), ("START", "not a UTC time")),
    "truncated file": (lambda t: t[:len(t) // 2], ("not well-formed XML",)),
    "wrong namespace / version (DIMAP v1 root)": (
        lambda t: t.replace("<PHR_Dimap_Document", "<Dimap_Document", 1).replace(
            "</PHR_Dimap_Document>", "</Dimap_Document>").replace("<Geometric_Data>", "<Geometric_Data_V1>").replace(
            "</Geometric_Data>", "</Geometric_Data_V1>"), ("Geometric_Data", "missing")),
    "empty file": (lambda t: "", ("neither scene JSON nor XML",)),
}


@pytest.mark.parametrize("case", list(CASES))
def test_broken_dimap_is_refused_naming_the_element(provider, shared_data, tmp_path, case):
    edit, texts = CASES[case]
    scene = _edited(shared_data, tmp_path, edit)
    out = tmp_path / "out"
    out.mkdir()
    assert_refused("pushbroom:footprint", _footprint(scene, str(out / "fp.gpkg")), "SCENE", scene.name, *texts,
                   watch=[tmp_path])


def test_binary_file_is_refused(provider, tmp_path):
    scene = tmp_path / "image.XML"
    scene.write_bytes(bytes(range(256)) * 64)
    assert_refused("pushbroom:footprint", _footprint(scene), "SCENE", "image.XML", watch=[tmp_path])


def test_directory_as_scene_is_refused(provider, tmp_path):
    folder = tmp_path / "product.XML"
    folder.mkdir()
    assert_refused("pushbroom:footprint", _footprint(folder), "SCENE", "product.XML", watch=[tmp_path])


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads any file: an unreadable file cannot be made")
def test_unreadable_file_is_refused(provider, shared_data, tmp_path):
    scene = _edited(shared_data, tmp_path, lambda t: t)
    scene.chmod(0)
    try:
        assert_refused("pushbroom:footprint", _footprint(scene), "SCENE", "product.XML", watch=[tmp_path])
    finally:
        scene.chmod(0o644)
