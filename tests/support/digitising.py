"""Driving the digitising docks in QGIS with mouse events (tests/qgis/test_digitising.py,
test_lines_roundtrip.py, test_digitising_gcps.py): a simulated scene with roads and its display copy,
the ground lines on the main canvas, and clicks on the canvases at image pixels or map coordinates.

The fixtures ``roads``, ``prepared`` and ``ground_layer`` are imported by the test modules that
use them."""
import csv

import numpy as np
import pytest
from osgeo import gdal
from qgis.core import QgsCoordinateReferenceSystem, QgsProject, QgsRectangle, QgsVectorLayer
from qgis.PyQt.QtCore import QPoint, Qt
from qgis.PyQt.QtTest import QTest

import processing


def blank_raw_image(path, cols: int, rows: int):
    """A raw image of the camera's size (sparse: blocks never written take no disk)."""
    gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte,
                                         options=["SPARSE_OK=TRUE", "TILED=YES"])  # closed when released
    return path


@pytest.fixture(scope="module")
def roads(plugin, tmp_path_factory):
    """A CBERS-02B HRC scene with 6 roads, its raw image (blank) and its display copy."""
    from pushbroom_adjust.core.formats import load_scene
    from pushbroom_adjust.simulation.simulator import simulate
    folder = tmp_path_factory.mktemp("roads")
    result = simulate("cbers02b_hrc", folder / "sim", seed=5, n_gcps=12, n_lines=6)
    camera = load_scene(result.true_scene).cameras[0]
    raw = blank_raw_image(folder / "raw.tif", camera.cols, camera.rows)
    with open(result.folder / "line_points.csv", newline="") as f:
        points = list(csv.DictReader(f))
    return {"result": result, "raw": raw, "folder": folder, "points": points, "camera": camera}


@pytest.fixture(scope="module")
def prepared(provider, roads):
    """The results of pushbroom:preparedigitising on the ``roads`` raw image (camera HRC): the
    display copy (OUTPUT, display.vrt) and the empty image lines layer (OUTPUT_LINES, empty.gpkg)."""
    out = roads["folder"]
    done = processing.run("pushbroom:preparedigitising", {
        "INPUT": str(roads["raw"]), "SCENE": str(roads["result"].true_scene), "CAMERA": "HRC",
        "OUTPUT": str(out / "display.vrt"), "OUTPUT_LINES": str(out / "empty.gpkg")})
    return done


@pytest.fixture()
def ground_layer(roads, qgis_canvas, qgis_new_project):
    """The ``roads`` ground lines layer in a new project, shown on the main canvas (800 x 800 px,
    EPSG:4326) zoomed to its extent."""
    layer = QgsVectorLayer(f"{roads['result'].lines}|layername=ground_lines", "roads", "ogr")
    assert layer.isValid()
    QgsProject.instance().addMapLayer(layer)
    qgis_canvas.resize(800, 800)
    qgis_canvas.setDestinationCrs(QgsCoordinateReferenceSystem("EPSG:4326"))
    qgis_canvas.setLayers([layer])
    qgis_canvas.setExtent(layer.extent())
    qgis_canvas.refresh()
    return layer


def true_points(roads, line_id) -> np.ndarray:
    """(n, 2) true image positions (col, row) of the road ``line_id`` of the ``roads`` fixture."""
    return np.array([[float(p["col_true"]), float(p["row_true"])] for p in roads["points"]
                     if p["line_id"] == line_id])


def click(canvas, x, y, button=Qt.LeftButton):
    """A mouse click at screen pixel (x, y) of ``canvas``."""
    QTest.mouseClick(canvas.viewport(), button, Qt.NoModifier, QPoint(int(x), int(y)))


def digitise(dock, pixels) -> np.ndarray:
    """Click the screen pixels nearest to image pixels (col, row) on the dock's canvas; returns
    the image positions the clicks stand for (through the canvas transform)."""
    transform = dock.canvas.getCoordinateTransform()
    clicked = []
    for col, row in pixels:
        screen = transform.transform(col, -row)
        x, y = round(screen.x()), round(screen.y())
        click(dock.canvas, x, y)
        at = transform.toMapCoordinates(x, y)
        clicked.append((at.x(), -at.y()))
    return np.array(clicked)


def zoom_to(canvas, pixels, margin=20.0):
    """Zoom the dock's ``canvas`` (image pixels, rows down) to image pixels (n, 2) with ``margin`` px."""
    canvas.setExtent(QgsRectangle(pixels[:, 0].min() - margin, -pixels[:, 1].max() - margin,
                                  pixels[:, 0].max() + margin, -pixels[:, 1].min() + margin))
    canvas.refresh()


def pick(main, lon, lat):
    """Click the main canvas (EPSG:4326) at (lon, lat)."""
    screen = main.getCoordinateTransform().transform(lon, lat)
    click(main, screen.x(), screen.y())


def click_pixel(dock, pixel, margin: float = 3.0) -> np.ndarray:
    """Zoom the dock's canvas to ``margin`` px around image pixel (col, row) (the view's centre
    a fraction of a pixel away, so that the click falls between screen pixels as a person's does)
    and click it there; the image position the click stands for."""
    zoom_to(dock.canvas, np.array([pixel]) + [0.37, -0.21], margin)
    return digitise(dock, [pixel])[0]


def pick_ground(main, lon: float, lat: float, half_deg: float = 5e-6) -> None:
    """Zoom the main canvas (EPSG:4326) to +-``half_deg`` around (lon, lat) and click there (the
    offscreen canvas is a few dozen screen pixels high: +-0.5 m is a few cm per screen pixel)."""
    main.setExtent(QgsRectangle(lon - half_deg, lat - half_deg, lon + half_deg, lat + half_deg))
    main.refresh()
    pick(main, lon, lat)
