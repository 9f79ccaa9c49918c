"""Run inside the QGIS desktop by scripts/screenshots.py (see there): measures, adjusts, digitises and
photographs. Not a module to import."""
import csv
import traceback
from pathlib import Path

from qgis.core import (QgsApplication, QgsCoordinateReferenceSystem, QgsCoordinateTransform, QgsPointXY, QgsProject,
                       QgsRasterLayer, QgsRectangle, QgsVectorLayer)
from qgis.gui import QgsMapCanvas
from qgis.PyQt.QtCore import Qt, QTimer
from qgis.PyQt.QtTest import QTest
from qgis.utils import iface, plugins

import processing
from tests.support.desktop import driver_arguments, quit_qgis, record_exceptions, write_result
from tests.support.digitising import click, click_pixel

ARGS = driver_arguments()
OUT = Path(ARGS["out"])
WINDOW = (1600, 1000)
SEEN = {"exceptions": [], "messages": [], "saved": []}
record_exceptions(SEEN["exceptions"])


def settle(rounds: int = 30) -> None:
    for _ in range(rounds):
        QgsApplication.processEvents()


def to_map(lon: float, lat: float) -> QgsPointXY:
    canvas = iface.mapCanvas()
    return QgsCoordinateTransform(QgsCoordinateReferenceSystem("EPSG:4326"), canvas.mapSettings().destinationCrs(),
                                  QgsProject.instance()).transform(QgsPointXY(lon, lat))


def pick(lon: float, lat: float, half: float = 0.5) -> None:
    """Zoom the main map to +-``half`` m around (lon, lat) and click there."""
    canvas = iface.mapCanvas()
    at = to_map(lon, lat)
    canvas.setExtent(QgsRectangle(at.x() - half, at.y() - half, at.x() + half, at.y() + half))
    canvas.refresh()
    screen = canvas.getCoordinateTransform().transform(at.x(), at.y())
    click(canvas, screen.x(), screen.y())


def show_main(lonlats, margin: float) -> None:
    """The main map around ``lonlats`` with ``margin`` m."""
    points = [to_map(lon, lat) for lon, lat in lonlats]
    xs, ys = [p.x() for p in points], [p.y() for p in points]
    iface.mapCanvas().setExtent(QgsRectangle(min(xs) - margin, min(ys) - margin, max(xs) + margin, max(ys) + margin))
    iface.mapCanvas().refresh()


def add_layer(layer):
    QgsProject.instance().addMapLayer(layer)
    settle()
    return layer


def grab(widget, name: str) -> None:
    """Save a picture of ``widget`` once its map canvases have drawn."""
    for _ in range(3):
        settle()
        for canvas in [iface.mapCanvas()] + widget.findChildren(QgsMapCanvas):
            canvas.waitWhileRendering()
    settle()
    path = OUT / name
    widget.grab().save(str(path))
    SEEN["saved"].append(str(path))


def five_points(block: dict) -> list[dict]:
    """Five GCPs seen well inside every scene of the block (their truth from gcps.csv)."""
    with open(block["gcps"], newline="") as f:
        rows = list(csv.DictReader(f))
    by_id = {}
    for r in rows:
        by_id.setdefault(r["id"], {})[r["scene"]] = r
    inside = [i for i, seen in by_id.items() if set(seen) == set(block["names"])
              and all(60 < float(r[k]) < 740 for r in seen.values() for k in ("col_true", "row_true"))]
    chosen = sorted(inside, key=lambda s: int(s[1:]))[:5]
    return [{"pixels": {n: (float(by_id[i][n]["col_true"]), float(by_id[i][n]["row_true"])) for n in block["names"]},
             "lon": float(by_id[i][block["names"][0]]["lon_true"]),
             "lat": float(by_id[i][block["names"][0]]["lat_true"])} for i in chosen]


def gcp_dock(plugin) -> None:
    block = ARGS["block"]
    add_layer(QgsRasterLayer(block["reference"], "reference"))
    dem = add_layer(QgsRasterLayer(block["dem"], "dem"))
    QgsProject.instance().layerTreeRoot().findLayer(dem.id()).setItemVisibilityChecked(False)  # the orthoimage shows
    plugin.gcp_action.trigger()
    dock = plugin.gcp_dock
    dock.dem_combo.setLayer(dem)
    dock.datum_combo.setCurrentText("geoid")
    for scene in block["scenes"]:
        dock.add_scene(scene)
    points = five_points(block)
    for point in points:
        QTest.mouseClick(dock.new_button, Qt.LeftButton)
        for k, name in enumerate(block["names"]):
            dock.scene_list.setCurrentRow(k)
            click_pixel(dock, point["pixels"][name])
        QTest.mouseClick(dock.ground_button, Qt.LeftButton)
        pick(point["lon"], point["lat"])
        SEEN["messages"].append(dock.message_label.text())
    work = Path(ARGS["work"])
    dock.save(str(work / "gcps.gpkg"))
    SEEN["messages"].append(dock.message_label.text())
    processing.run("pushbroom:bundleadjust", {"SCENES": block["scenes"], "GCPS": str(work / "gcps.gpkg"),
                                              "POSITION_ORDER": 0, "ATTITUDE_ORDER": 0,
                                              "OUTPUT_FOLDER": str(work / "adjusted")})
    dock.open_layer(str(work / "adjusted" / "adjusted_gcps.gpkg"))
    SEEN["messages"].append(dock.message_label.text())
    dock.scene_list.setCurrentRow(1)
    dock.select_point(2)
    dock.canvas.zoom_to_pixel(*points[2]["pixels"][block["names"][1]], 16.0)
    show_main([(p["lon"], p["lat"]) for p in points], 400.0)
    dock.raise_()
    grab(iface.mainWindow(), "gcp-dock.png")


def lines_dock(plugin) -> None:
    roads = ARGS["roads"]
    add_layer(QgsRasterLayer(roads["reference"], "reference (roads)"))
    ground = add_layer(QgsVectorLayer(f"{roads['lines']}|layername=ground_lines", "ground lines", "ogr"))
    plugin.action.trigger()
    dock = plugin.dock
    dock.open_image(roads["scene"])
    dock.ground_combo.setLayer(ground)
    dock.id_combo.setField("line_id")
    with open(roads["points"], newline="") as f:
        rows = list(csv.DictReader(f))
    for line_id in ("R1", "R2"):
        clicks = [(float(r["col_click"]), float(r["row_click"])) for r in rows if r["line_id"] == line_id][::2]
        dock.canvas.zoom_to_image()
        settle()
        transform = dock.canvas.getCoordinateTransform()
        for col, row in clicks:
            screen = transform.transform(col, -row)
            click(dock.canvas, screen.x(), screen.y())
        click(dock.canvas, 5, 5, Qt.RightButton)
        QTest.mouseClick(dock.pair_button, Qt.LeftButton)
        feature = next(f for f in ground.getFeatures() if f["line_id"] == line_id)
        vertices = feature.geometry().asPolyline() or feature.geometry().asMultiPolyline()[0]
        middle = vertices[len(vertices) // 2]
        pick(middle.x(), middle.y(), 20.0)
        SEEN["messages"].append(dock.message_label.text())
    QTest.mouseClick(dock.snap_button, Qt.LeftButton)
    SEEN["messages"].append(dock.message_label.text())
    QTest.mouseClick(dock.predict_button, Qt.LeftButton)
    SEEN["messages"].append(dock.message_label.text())
    dock.form_action.setChecked(False)  # the settings folded away: the canvas takes the dock
    vertices = dock.editor.lines[dock.editor.selected].vertices
    dock.canvas.zoom_to_pixel(*vertices[len(vertices) // 2], 90.0)
    iface.mapCanvas().setExtent(iface.mapCanvas().mapSettings().layerExtentToOutputExtent(ground, ground.extent()))
    iface.mapCanvas().refresh()
    dock.raise_()
    grab(iface.mainWindow(), "lines-dock.png")


def dialogs() -> None:
    for alg_id in ARGS["dialogs"]:
        dialog = processing.createAlgorithmDialog(alg_id)
        dialog.resize(1000, 900)
        dialog.show()
        grab(dialog, f"{alg_id.split(':')[-1]}-dialog.png")
        dialog.close()


def run() -> None:
    try:
        iface.mainWindow().move(0, 0)
        iface.mainWindow().resize(*WINDOW)
        plugin = plugins["pushbroom_adjust"]
        gcp_dock(plugin)
        lines_dock(plugin)
        dialogs()
    except Exception:  # every failure is reported by scripts/screenshots.py
        SEEN["exceptions"].append(traceback.format_exc())
    write_result(ARGS, SEEN)
    quit_qgis()


QTimer.singleShot(1000, run)
