"""pushbroom:importtiepoints — tie points (image observations of unknown ground points) from CSV
or a layer, checked against a scene, intersected with its onboard model and written as the
GeoPackage tie-point layer."""
from qgis.core import (QgsProcessing, QgsProcessingException, QgsProcessingParameterFeatureSource,
                       QgsProcessingParameterFile, QgsProcessingParameterVectorDestination)

from ...core.observations import tiepoints
from ...core.observations.tables import per_point_sigmas
from ..feedback import check_cancelled, core_call, core_log_to
from ..inputs import (add_scene_parameters, attribute_floats, attribute_texts, field_values, load_scene_for,
                      source_features)
from ..outputs import geopackage_output, write_tie_layer
from ..parameters import (CAMERA_FIELD, COL_FIELD, ID_FIELD, ROW_FIELD, SCENE, SCENE_FIELD, SIGMA_FIELDS, SIGMA_PX,
                          camera_field, id_field, image_field, scene_field, sigma_field, sigma_px, tr)
from .base import PushbroomAlgorithm


class ImportTiePointsAlgorithm(PushbroomAlgorithm):
    ID = "importtiepoints"
    NAME = "Import tie points"
    GROUP, GROUP_ID = "Control", "control"
    HELP = ("Reads tie points — image positions (col, row) of ground points whose coordinates are unknown, one row "
            "per point and camera — from a CSV file or a layer, checks them against the scene and intersects "
            "every point seen in two or more cameras with the scene's (onboard) model. Refused: a camera the "
            "scene lacks, the same point twice in one camera, observations outside their camera's image, all "
            "points in one image corner or on a line. Kept with a warning: points seen in one camera only (not "
            "intersected; the adjustment leaves them out) and points whose a-priori intersection residual is "
            "implausible (more than 3 x the median point's and 5 px: likely mismatched). Image coordinates "
            "follow GDAL: (0, 0) is the upper-left corner of the upper-left pixel. The output is a GeoPackage "
            "point layer 'tie_points' in EPSG:4979, one feature per observation, located at its point's "
            "onboard intersection (empty geometry where there is none), with fields id, camera, col, row, "
            "sigma_px, scene, rays, res_col, res_row, res_px (a-priori intersection residuals, px).")
    INPUT_FILE, INPUT, OUTPUT = "INPUT_FILE", "INPUT", "OUTPUT"
    ID_FIELD, CAMERA_FIELD, COL_FIELD, ROW_FIELD = ID_FIELD, CAMERA_FIELD, COL_FIELD, ROW_FIELD
    SCENE_FIELD, SIGMA_PX, SIGMA_PX_FIELD = SCENE_FIELD, SIGMA_PX, SIGMA_FIELDS["sigma_px"]

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False)
        self.add_parameter(QgsProcessingParameterFile(self.INPUT_FILE, tr("Tie-point file (CSV)"), optional=True,
                                                      fileFilter="Tie-point files (*.csv *.txt);;All files (*)"),
                           tr("Delimited text with a header row (delimiter , ; TAB or | detected; decimal commas "
                              "accepted with ; TAB |), one row per point and camera; other columns are ignored. The "
                              "columns id, camera, col and row are read under these names unless ID_FIELD, "
                              "CAMERA_FIELD, COL_FIELD or ROW_FIELD name others, so the simulator's tie_points.csv "
                              "needs no field parameter. Give this or INPUT, not both."))
        self.add_parameter(QgsProcessingParameterFeatureSource(self.INPUT, tr("Tie-point layer or table"),
                                                               [QgsProcessing.TypeVector], optional=True),
                           tr("A layer or table whose fields hold the observations (its geometry, if any, is "
                              "ignored). Give this or INPUT_FILE, not both."))
        self.addParameter(id_field())
        self.addParameter(camera_field())
        self.addParameter(image_field(self.COL_FIELD))
        self.addParameter(image_field(self.ROW_FIELD))
        self.addParameter(scene_field())
        self.addParameter(sigma_px())
        self.addParameter(sigma_field("sigma_px"))
        out = QgsProcessingParameterVectorDestination(self.OUTPUT, tr("Tie points"), QgsProcessing.TypeVectorPoint)
        out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(out, tr("GeoPackage (.gpkg) point layer of the checked observations, styled by the number "
                                   "of cameras seeing each point, with likely mismatches standing out."))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        dest = geopackage_output(self, parameters, context, self.OUTPUT, "tie_points.gpkg", "tie-point layers")
        scene_path = self.parameterAsFile(parameters, SCENE, context)
        scene = load_scene_for(SCENE, scene_path, feedback)
        feedback.setProgress(10)
        with core_log_to(feedback, tiepoints.__name__):
            table = self._read(parameters, context)
            check_cancelled(feedback)
            feedback.setProgressText(f"checking and intersecting {len(table)} observations against {scene_path}")
            feedback.setProgress(30)
            table = core_call(tiepoints.check_against_scene, table, scene, scene_path)
        check_cancelled(feedback)
        feedback.setProgress(80)
        return write_tie_layer(table, self.OUTPUT, dest, context, feedback)

    def _read(self, parameters, context) -> tiepoints.TieTable:
        path = self.parameterAsFile(parameters, self.INPUT_FILE, context)
        source = self.parameterAsSource(parameters, self.INPUT, context)
        if bool(path) == (source is not None):
            raise QgsProcessingException(f"give either {self.INPUT_FILE} (CSV) or {self.INPUT} (layer or table), "
                                         f"not {'both' if path else 'neither'}")
        sigma = self.parameterAsDouble(parameters, self.SIGMA_PX, context)
        if source is not None:
            return self._from_layer(parameters, context, source, sigma)
        text = {name: self.parameterAsString(parameters, name, context).strip() or None
                for name in (self.ID_FIELD, self.CAMERA_FIELD, self.COL_FIELD, self.ROW_FIELD, self.SCENE_FIELD,
                             self.SIGMA_PX_FIELD)}
        # ID_FIELD empty: the column 'id' (the core names the file and its columns when there is none)
        mapping = tiepoints.CsvMapping(id=text[self.ID_FIELD] or "id", camera=text[self.CAMERA_FIELD],
                                       col=text[self.COL_FIELD] or "col", row=text[self.ROW_FIELD] or "row",
                                       scene=text[self.SCENE_FIELD], sigma_px=text[self.SIGMA_PX_FIELD])
        return core_call(tiepoints.read_csv, path, mapping, sigma)

    def _from_layer(self, parameters, context, source, sigma: float) -> tiepoints.TieTable:
        """Arrays of the layer's features -> core.tiepoints.build_table (which checks them)."""
        features = source_features(self.INPUT, source)
        column = field_values(self, parameters, context, source, features)
        ids = attribute_texts(column(self.ID_FIELD, True, "id"))
        what = f"{self.INPUT} layer"
        sigmas = column(self.SIGMA_PX_FIELD, False)
        if sigmas is not None:
            sigma = core_call(per_point_sigmas, attribute_texts(sigmas), sigma,
                              self.parameterAsString(parameters, self.SIGMA_PX_FIELD, context).strip(), ids, what,
                              "sigma_px")
        return core_call(tiepoints.build_table, ids, attribute_texts(column(self.CAMERA_FIELD, False, "camera")),
                         attribute_floats(column(self.COL_FIELD, True)), attribute_floats(column(self.ROW_FIELD, True)),
                         scene=attribute_texts(column(self.SCENE_FIELD, False, "scene")), sigma_px=sigma, source=what)
