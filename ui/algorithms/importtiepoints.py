"""pushbroom:importtiepoints — tie points (image observations of unknown ground points) from CSV
or a layer, checked against a scene, intersected with its onboard model and written as the
GeoPackage tie-point layer."""
from qgis.core import QgsProcessing, QgsProcessingException, QgsProcessingParameterFeatureSource, \
    QgsProcessingParameterFile

from ...core.observations import tiepoints
from ...core.runs import importtiepoints as use_case
from ..inputs import (SCENE_PARAMETERS, add_scene_parameters, attribute_floats, attribute_texts, field_values,
                      source_features)
from ..outputs import STYLES, files_in_use, style_output_on_load
from ..parameters import (CAMERA_FIELD, COL_FIELD, ID_FIELD, ROW_FIELD, SCENE, SCENE_FIELD, SIGMA_FIELDS, SIGMA_PX,
                          file_layer, image_field, point_field, sigma_px, tr)
from .base import PushbroomAlgorithm


class ImportTiePointsAlgorithm(PushbroomAlgorithm):
    ID = "importtiepoints"
    NAME = "Import tie points"
    GROUP, GROUP_ID = "Control", "control"
    INPUT_FILE, INPUT, OUTPUT = "INPUT_FILE", "INPUT", "OUTPUT"
    ID_FIELD, CAMERA_FIELD, COL_FIELD, ROW_FIELD = ID_FIELD, CAMERA_FIELD, COL_FIELD, ROW_FIELD
    SCENE_FIELD, SIGMA_PX, SIGMA_PX_FIELD = SCENE_FIELD, SIGMA_PX, SIGMA_FIELDS["sigma_px"]
    CORE_PARAMETERS = SCENE_PARAMETERS

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False)
        self.addParameter(QgsProcessingParameterFile(self.INPUT_FILE, tr("Tie-point file (CSV)"), optional=True,
                                                     fileFilter="Tie-point files (*.csv *.txt);;All files (*)"))
        self.addParameter(QgsProcessingParameterFeatureSource(self.INPUT, tr("Tie-point layer or table"),
                                                              [QgsProcessing.TypeVector], optional=True))
        for parameter in (point_field(ID_FIELD), point_field(CAMERA_FIELD), image_field(COL_FIELD),
                          image_field(ROW_FIELD), point_field(SCENE_FIELD), sigma_px(),
                          point_field(self.SIGMA_PX_FIELD),
                          file_layer(self.OUTPUT, tr("Tie points"), QgsProcessing.TypeVectorPoint)):
            self.addParameter(parameter)
        self.show_only("SCENE", "INPUT_FILE", "INPUT", "SIGMA_PX")

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        path = self.parameterAsFile(parameters, self.INPUT_FILE, context)
        source = self.parameterAsSource(parameters, self.INPUT, context)
        if bool(path) == (source is not None):
            raise QgsProcessingException(f"give either {self.INPUT_FILE} (CSV) or {self.INPUT} (layer or table), "
                                         f"not {'both' if path else 'neither'}")
        text = {name: self.parameterAsString(parameters, name, context).strip() or None
                for name in (self.ID_FIELD, self.CAMERA_FIELD, self.COL_FIELD, self.ROW_FIELD, self.SCENE_FIELD,
                             self.SIGMA_PX_FIELD)}
        # ID_FIELD empty: the column 'id' (the core names the file and its columns when there is none)
        mapping = tiepoints.CsvMapping(id=text[self.ID_FIELD] or "id", camera=text[self.CAMERA_FIELD],
                                       col=text[self.COL_FIELD] or "col", row=text[self.ROW_FIELD] or "row",
                                       scene=text[self.SCENE_FIELD], sigma_px=text[self.SIGMA_PX_FIELD])
        result = self.run_core(use_case.run, use_case.ImportTiesRequest(
            self.output_path(parameters, context, self.OUTPUT, "tie_points.gpkg"),
            self.parameterAsFile(parameters, SCENE, context), path, mapping,
            self._columns(parameters, context, source, text[self.SIGMA_PX_FIELD]) if source is not None else None,
            self.parameterAsDouble(parameters, self.SIGMA_PX, context), files_in_use(self, parameters, context)),
            feedback)
        style_output_on_load(context, result.files[self.OUTPUT], STYLES / "tie_points.qml")
        return result.files

    def _columns(self, parameters, context, source, sigma_field: str | None) -> use_case.TieColumns:
        """The observations of the INPUT layer's features (fields as the *_FIELD parameters name them)."""
        features = source_features(self.INPUT, source)
        column = field_values(self, parameters, context, source, features)
        ids = attribute_texts(column(self.ID_FIELD, True, "id"))
        sigmas = column(self.SIGMA_PX_FIELD, False)
        return use_case.TieColumns(ids, attribute_texts(column(self.CAMERA_FIELD, False, "camera")),
                                   attribute_floats(column(self.COL_FIELD, True)),
                                   attribute_floats(column(self.ROW_FIELD, True)),
                                   attribute_texts(column(self.SCENE_FIELD, False, "scene")),
                                   None if sigmas is None else (attribute_texts(sigmas), sigma_field or ""),
                                   f"{self.INPUT} layer")
