"""Driver run inside the real QGIS desktop by tests/qgis/test_docks_desktop.py (through
tests/support/desktop.py): from start-up to closing both docks, as a new user would, with only an
orthoimage loaded (no DEM). It records what QGIS logged (the Log Messages panel since start-up, the
message log and the message bar during the run, Python exceptions) and what the docks did, writes
that as JSON and quits QGIS. The test asserts on it."""
import traceback
from pathlib import Path

from qgis.core import (QgsApplication, QgsCoordinateReferenceSystem, QgsCoordinateTransform, QgsFeature, QgsGeometry,
                       QgsPointXY, QgsProject, QgsRasterLayer, QgsRectangle, QgsVectorLayer)
from qgis.PyQt.QtCore import Qt, QTimer
from qgis.PyQt.QtTest import QTest
from qgis.PyQt.QtXml import QDomDocument
from qgis.PyQt.QtWidgets import QApplication, QMenu, QPlainTextEdit, QToolButton
from qgis.utils import iface, plugins, unloadPlugin

from tests.support.desktop import driver_arguments, quit_qgis, record_exceptions, write_result
from tests.support.digitising import click, click_pixel

ARGS = driver_arguments()
SEEN = {"exceptions": [], "log": []}


record_exceptions(SEEN["exceptions"])
QgsApplication.messageLog().messageReceived.connect(lambda text, tag, level: SEEN["log"].append((int(level), tag,
                                                                                                 text)))


def settle(rounds: int = 20) -> None:
    """Let queued events (renders, queued log messages, red bars) happen."""
    for _ in range(rounds):
        QgsApplication.processEvents()


def startup_log() -> str:
    """The text of every tab of the Log Messages panel (what QGIS logged since it started)."""
    return "\n".join(w.toPlainText() for w in iface.mainWindow().findChildren(QPlainTextEdit))


def entry_points(plugin) -> dict:
    """Where the docks can be opened from besides the toolbar: the Processing menu's submenu and
    the provider's button of the Processing toolbox."""
    processing = iface.mainWindow().menuBar().findChild(QMenu, "processing")
    ours = [a.menu() for a in processing.actions() if a.menu() is not None and a.text() == "Pushbroom Adjust"]
    button = iface.mainWindow().findChild(QToolButton, "provideraction_pushbroom")
    return {"processing_menu": [a.text() for a in ours[0].actions()] if ours else [],
            "toolbox": [a.text() for a in button.menu().actions()] if button is not None else [],
            "icons_differ": plugin.action.icon().cacheKey() != plugin.gcp_action.icon().cacheKey()}


def pick_lonlat(canvas, lon: float, lat: float, half: float = 0.5) -> None:
    """Zoom the main map (any CRS) to +-``half`` map units around (lon, lat) and click there."""
    to_map = QgsCoordinateTransform(QgsCoordinateReferenceSystem("EPSG:4326"), canvas.mapSettings().destinationCrs(),
                                    QgsProject.instance())
    at = to_map.transform(QgsPointXY(lon, lat))
    canvas.setExtent(QgsRectangle(at.x() - half, at.y() - half, at.x() + half, at.y() + half))
    canvas.refresh()
    screen = canvas.getCoordinateTransform().transform(at.x(), at.y())
    click(canvas, screen.x(), screen.y())


def offered(box) -> list[str]:
    return [box.layer(k).name() for k in range(box.count()) if box.layer(k) is not None]


def measure_gcp(dock, point: dict) -> dict:
    """Measure a point in both scenes by clicks, its ground picked on the main map; save it and
    read it back."""
    from pushbroom_adjust.core.observations.gcps import read_gpkg
    QTest.mouseClick(dock.new_button, Qt.LeftButton)
    for k, name in enumerate(ARGS["names"]):
        dock.scene_list.setCurrentRow(k)
        click_pixel(dock, point["pixels"][name])
    QTest.mouseClick(dock.ground_button, Qt.LeftButton)
    pick_lonlat(iface.mapCanvas(), point["lon"], point["lat"])
    settle()
    done = {"message": dock.message_label.text(), "h": dock.editor.current().ground.h,
            "table": [dock.table.item(0, k).text() for k in range(dock.table.columnCount())]}
    done["saved"] = dock.save(ARGS["gcps"])
    done["saved_h"] = read_gpkg(ARGS["gcps"]).h.tolist() if done["saved"] else None
    return done


def uncovered_dem(dock, point: dict) -> dict:
    """A DEM that does not cover the point: named, no ground given, nothing saved."""
    dem = QgsRasterLayer(ARGS["far_dem"], "far dem")
    QgsProject.instance().addMapLayer(dem)
    dock.dem_combo.setLayer(dem)
    QTest.mouseClick(dock.new_button, Qt.LeftButton)
    dock.scene_list.setCurrentRow(0)
    click_pixel(dock, point["pixels"][ARGS["names"][0]])
    QTest.mouseClick(dock.ground_button, Qt.LeftButton)
    pick_lonlat(iface.mapCanvas(), point["lon"], point["lat"])
    settle()
    result = {"message": dock.message_label.text(), "ground": dock.editor.current().ground is not None,
              "offered": offered(dock.dem_combo)}
    result["saved"] = dock.save(ARGS["gcps_far"])
    result["save_message"] = dock.message_label.text()
    QApplication.setActiveWindow(iface.mainWindow())  # no window manager activates it under xvfb
    dock.canvas.setFocus()
    settle()
    result["focus"] = type(QApplication.focusWidget()).__name__
    QTest.keyClick(dock.canvas, Qt.Key_Delete)
    result["after_delete"] = [p.id for p in dock.editor.points]
    QTest.keyClick(dock.canvas, Qt.Key_Z, Qt.ControlModifier)
    result["after_undo"] = [p.id for p in dock.editor.points]
    result["undo_message"] = dock.message_label.text()
    dock.dem_combo.setLayer(None)
    return result


def lines_dock(dock, line: list) -> dict:
    """Open the first scene, digitise a line, predict the ground lines without a DEM."""
    layer = QgsVectorLayer("LineString?crs=EPSG:4326&field=line_id:string", "roads", "memory")
    feature = QgsFeature(layer.fields())
    feature.setGeometry(QgsGeometry.fromPolylineXY([QgsPointXY(*p) for p in line]))
    feature["line_id"] = "R1"
    layer.dataProvider().addFeatures([feature])
    QgsProject.instance().addMapLayer(layer)
    opened = dock.open_image(ARGS["scenes"][0])
    dock.ground_combo.setLayer(layer)
    dock.id_combo.setField("line_id")
    dock.height_combo.setCurrentText("dem")
    for x, y in ((100, 100), (200, 150)):
        click(dock.canvas, x, y)
    click(dock.canvas, 220, 160, Qt.RightButton)
    QTest.mouseClick(dock.predict_button, Qt.LeftButton)
    settle()
    return {"opened": opened, "offered": offered(dock.dem_combo), "dem": dock.dem_combo.currentLayer() is not None,
            "lines": len(dock.editor.lines), "message": dock.message_label.text()}


def run() -> None:
    try:
        SEEN["startup"] = startup_log()
        plugin = plugins["pushbroom_adjust"]
        SEEN["entry_points"] = entry_points(plugin)
        reference = QgsRasterLayer(ARGS["reference"], "reference")
        QgsProject.instance().addMapLayer(reference)
        settle()  # the map takes the orthoimage's CRS (UTM)
        iface.mapCanvas().setExtent(reference.extent())
        plugin.gcp_action.trigger()
        gcp = plugin.gcp_dock
        SEEN["gcp_dem"] = {"current": gcp.dem_combo.currentLayer() is not None, "offered": offered(gcp.dem_combo)}
        SEEN["added"] = [(gcp.add_scene(path), gcp.message_label.text()) for path in ARGS["scenes"]]
        settle()
        SEEN["gcp"] = measure_gcp(gcp, ARGS["point"])
        SEEN["far"] = uncovered_dem(gcp, ARGS["point"])
        plugin.action.trigger()
        SEEN["tabified"] = plugin.dock in iface.mainWindow().tabifiedDockWidgets(gcp)
        SEEN["lines"] = lines_dock(plugin.dock, ARGS["ground_line"])
        QgsProject.instance().write(ARGS["project"])
        document = QDomDocument()
        document.setContent(Path(ARGS["project"]).read_bytes())
        # what a project read tells every canvas (the project's CRS and extent); reading the file itself
        # also makes QGIS open its own world map, on which GDAL warns on stderr
        QgsProject.instance().readProject.emit(document)
        settle()
        SEEN["after_project_read"] = gcp.canvas.mapSettings().destinationCrs().isValid()
        gcp.close()
        plugin.dock.close()
        settle()
        unloadPlugin("pushbroom_adjust")
        settle()
        SEEN["bar"] = [(int(item.level()), item.title(), item.text()) for item in iface.messageBar().items()]
    except Exception:  # every failure is recorded for the test
        SEEN["exceptions"].append(traceback.format_exc())
    write_result(ARGS, SEEN)
    quit_qgis()


QTimer.singleShot(500, run)
