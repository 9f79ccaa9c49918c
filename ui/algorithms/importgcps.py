"""pushbroom:importgcps — ground control points from CSV, QGIS .points or a point layer,
checked against a scene and written as the GeoPackage GCP layer the adjustment reads."""
from qgis.core import (QgsProcessing, QgsProcessingException, QgsProcessingParameterCrs,
                       QgsProcessingParameterFeatureSource, QgsProcessingParameterFile, QgsProcessingParameterNumber,
                       QgsProcessingParameterString, QgsWkbTypes)

from ...core.observations import gcps
from ...core.runs import importgcps as use_case
from ..inputs import (SCENE_PARAMETERS, add_dem_parameters, add_scene_parameters, attribute_floats, attribute_texts,
                      crs_text, field_values, point_heights, point_xyz, require_points, scene_or_block,
                      source_features)
from ..outputs import STYLES, files_in_use, style_output_on_load
from ..parameters import (CAMERA, CAMERA_FIELD, CHECK_FRACTION, COL_FIELD, HEIGHT_SOURCE, ID_FIELD, ROW_FIELD,
                          SCENE_FIELD, SIGMA_FIELDS, SIGMA_PX, Z_DATUM, camera, check_fraction, file_layer,
                          height_source, image_field, point_field, sigma_px, tr, z_datum)
from .base import PushbroomAlgorithm


class ImportGcpsAlgorithm(PushbroomAlgorithm):
    ID = "importgcps"
    NAME = "Import ground control points"
    GROUP, GROUP_ID = "Control", "control"
    CAMERA = CAMERA
    INPUT_FILE, INPUT = "INPUT_FILE", "INPUT"
    ID_FIELD, COL_FIELD, ROW_FIELD, X_FIELD, Y_FIELD = ID_FIELD, COL_FIELD, ROW_FIELD, "X_FIELD", "Y_FIELD"
    Z_FIELD, ROLE_FIELD, CAMERA_FIELD, SCENE_FIELD = "Z_FIELD", "ROLE_FIELD", CAMERA_FIELD, SCENE_FIELD
    GROUND_CRS, HEIGHT_SOURCE, CHECK_FRACTION, Z_DATUM = "GROUND_CRS", HEIGHT_SOURCE, CHECK_FRACTION, Z_DATUM
    SIGMA_PX, SIGMA_XY, SIGMA_Z, OUTPUT = SIGMA_PX, "SIGMA_XY", "SIGMA_Z", "OUTPUT"
    SIGMA_FIELDS = SIGMA_FIELDS
    # The inputs core errors name (core.errors.InputError.parameter) -> this algorithm's parameters.
    CORE_PARAMETERS = {use_case.SCENE_COLUMN: SCENE_FIELD, use_case.CAMERA_COLUMN: CAMERA_FIELD, **SCENE_PARAMETERS}
    SCENE_OR_SCENES = ("check every point against one scene",
                       f"check each row against the scene of the block it names ({SCENE_FIELD})")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False, or_scenes=True)
        self.addParameter(camera())
        self.addParameter(QgsProcessingParameterFile(self.INPUT_FILE, tr("GCP file (CSV or QGIS .points)"),
                                                     optional=True,
                                                     fileFilter="GCP files (*.csv *.txt *.points);;All files (*)"))
        self.addParameter(QgsProcessingParameterFeatureSource(self.INPUT, tr("GCP point layer"),
                                                              [QgsProcessing.TypeVectorPoint], optional=True))
        self.addParameter(point_field(ID_FIELD))
        self.addParameter(image_field(self.COL_FIELD))
        self.addParameter(image_field(self.ROW_FIELD))
        for name, label, default in ((self.X_FIELD, tr("Ground X / longitude field (CSV)"), "lon"),
                                     (self.Y_FIELD, tr("Ground Y / latitude field (CSV)"), "lat"),
                                     (self.Z_FIELD, tr("Height field"), ""), (self.ROLE_FIELD, tr("Role field"), "")):
            self.addParameter(QgsProcessingParameterString(name, label, optional=True, defaultValue=default))
        self.addParameter(point_field(CAMERA_FIELD))
        self.addParameter(point_field(SCENE_FIELD))
        self.addParameter(QgsProcessingParameterCrs(self.GROUND_CRS, tr("Ground CRS (CSV and .points)"), optional=True,
                                                    defaultValue="EPSG:4326"))
        self.addParameter(height_source())
        self.addParameter(z_datum())
        add_dem_parameters(self)
        self.addParameter(check_fraction())
        self.addParameter(sigma_px())
        for name, label, default in ((self.SIGMA_XY, tr("Ground planimetric sigma (m)"), gcps.DEFAULT_SIGMA_XY),
                                     (self.SIGMA_Z, tr("Ground height sigma (m)"), gcps.DEFAULT_SIGMA_Z)):
            self.addParameter(QgsProcessingParameterNumber(name, label, QgsProcessingParameterNumber.Double, default,
                                                           minValue=0.0))
        for name in self.SIGMA_FIELDS.values():
            self.addParameter(point_field(name))
        self.addParameter(file_layer(self.OUTPUT, tr("Ground control points"), QgsProcessing.TypeVectorPoint))
        self.show_only("SCENE", "SCENES", "INPUT_FILE", "INPUT", "GROUND_CRS", "HEIGHT_SOURCE", "DEM", "HEIGHT")

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        scene, scenes = scene_or_block(self, parameters, context, feedback)
        path = self.parameterAsFile(parameters, self.INPUT_FILE, context)
        source = self.parameterAsSource(parameters, self.INPUT, context)
        if bool(path) == (source is not None):
            raise QgsProcessingException(f"give either {self.INPUT_FILE} (CSV or .points) or {self.INPUT} "
                                         f"(point layer), not {'both' if path else 'neither'}")
        text = {name: self.parameterAsString(parameters, name, context).strip() or None
                for name in (self.ID_FIELD, self.COL_FIELD, self.ROW_FIELD, self.X_FIELD, self.Y_FIELD, self.Z_FIELD,
                             self.ROLE_FIELD, self.CAMERA_FIELD, self.SCENE_FIELD, *self.SIGMA_FIELDS.values())}
        given = [name for name in (*self.SIGMA_FIELDS.values(), self.SCENE_FIELD) if text[name]]
        if path.lower().endswith(".points") and given:
            raise QgsProcessingException(f"{given[0]}: QGIS .points files have no such field (no per-point "
                                         "sigma, no scene); leave it empty or import a CSV")
        columns = self._columns(parameters, context, source) if source is not None else None
        crs = source.sourceCrs() if source is not None else self.parameterAsCrs(parameters, self.GROUND_CRS, context)
        result = self.run_core(use_case.run, use_case.ImportGcpsRequest(
            self.output_path(parameters, context, self.OUTPUT, "gcps.gpkg"),
            scene, scenes, path,
            gcps.CsvMapping(col=text[self.COL_FIELD], row=text[self.ROW_FIELD], x=text[self.X_FIELD],
                            y=text[self.Y_FIELD], id=text[self.ID_FIELD], z=text[self.Z_FIELD],
                            role=text[self.ROLE_FIELD], camera=text[self.CAMERA_FIELD], scene=text[self.SCENE_FIELD],
                            **{k: text[name] for k, name in self.SIGMA_FIELDS.items()}),
            columns, crs_text(crs), crs.authid(), point_heights(self, parameters, context),
            {f"sigma_{k}": self.parameterAsDouble(parameters, name, context)
             for k, name in (("px", self.SIGMA_PX), ("xy", self.SIGMA_XY), ("z", self.SIGMA_Z))},
            self.parameterAsString(parameters, self.CAMERA, context).strip() or None,
            self.parameterAsDouble(parameters, self.CHECK_FRACTION, context),
            files_in_use(self, parameters, context)), feedback)
        style_output_on_load(context, result.files[self.OUTPUT], STYLES / "gcps.qml")
        return result.files

    def _columns(self, parameters, context, source) -> use_case.GcpColumns:
        """The GCP columns of the INPUT layer's features (fields as the *_FIELD parameters name them)."""
        features = source_features(self.INPUT, source)  # an empty layer said first
        require_points(self.INPUT, source)
        column = field_values(self, parameters, context, source, features)
        xyz = point_xyz(features)
        z = column(self.Z_FIELD, False)
        if z is None and QgsWkbTypes.hasZ(source.wkbType()):
            z = xyz[:, 2]
        sigmas = {key: (attribute_texts(values), self.parameterAsString(parameters, name, context).strip())
                  for key, name in self.SIGMA_FIELDS.items() if (values := column(name, False)) is not None}
        texts = {name: attribute_texts(column(name, False, conventional))
                 for name, conventional in ((self.ROLE_FIELD, "role"), (self.CAMERA_FIELD, "camera"),
                                            (self.SCENE_FIELD, "scene"))}
        return use_case.GcpColumns(column(self.ID_FIELD, False, "id") or [f.id() for f in features],
                                   attribute_floats(column(self.COL_FIELD, True)),
                                   attribute_floats(column(self.ROW_FIELD, True)), xyz[:, 0], xyz[:, 1],
                                   None if z is None else attribute_floats(z), *texts.values(), sigmas,
                                   f"{self.INPUT} layer")
