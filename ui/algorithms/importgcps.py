"""pushbroom:importgcps — ground control points from CSV, QGIS .points or a point layer,
checked against a scene and written as the GeoPackage GCP layer the adjustment reads."""
import numpy as np
from qgis.core import (QgsCoordinateReferenceSystem, QgsProcessing, QgsProcessingException,
                       QgsProcessingParameterCrs, QgsProcessingParameterFeatureSource,
                       QgsProcessingParameterFile, QgsProcessingParameterNumber, QgsProcessingParameterString,
                       QgsProcessingParameterVectorDestination, QgsWkbTypes)

from ...core import observations
from ...core.observations import gcps
from ...core.observations.blockscenes import check_against_block
from ...core.observations.tables import per_point_sigmas
from ..blockmatch import block_given, one_scene_file, scene_files
from ..feedback import check_cancelled, core_call, core_log_to, processing_errors
from ..inputs import (add_dem_parameters, add_scene_parameters, attribute_floats, attribute_texts, block_scene_names,
                      field_values, heights_from_parameters, load_scene_for, require_points, source_features)
from ..outputs import STYLES, geopackage_output, style_output_on_load
from ..parameters import (CAMERA, CAMERA_FIELD, CHECK_FRACTION, COL_FIELD, HEIGHT_SOURCE, ID_FIELD, ROW_FIELD, SCENE,
                          SCENE_FIELD, SCENES, SIGMA_FIELDS, SIGMA_PX, Z_DATUM, camera, camera_field, check_fraction,
                          height_source, id_field, image_field, scene_field, sigma_field, sigma_px, tr, z_datum)
from .base import PushbroomAlgorithm


class ImportGcpsAlgorithm(PushbroomAlgorithm):
    ID = "importgcps"
    NAME = "Import ground control points"
    GROUP, GROUP_ID = "Control", "control"
    HELP = ("Reads ground control points (image col/row + ground coordinates) from a CSV file, a QGIS "
            "Georeferencer <i>.points</i> file or a point layer, converts the ground coordinates to WGS84 and "
            "the heights to ellipsoidal, and checks every point against the scene's sensor model: the "
            "a-priori residual is the model's projection of the ground point minus the measured image "
            "position (px, and metres on the ground). Points outside the image are kept and flagged "
            "(inside = 0), never dropped. Image coordinates follow GDAL: (0, 0) is the upper-left corner "
            "of the upper-left pixel. In .points files the pixel y is negative downwards (QGIS shows raw "
            "images so) and is converted; disabled .points entries become check points. The output is a "
            "GeoPackage point layer in EPSG:4979 (lon, lat, ellipsoidal height) with fields id, role, "
            "camera, col, row, h, sigma_px, sigma_xy, sigma_z, res_col, res_row, res_px, res_m, inside. "
            "CHECK_FRACTION's check points are chosen deterministically, spread along the image; points already "
            "'check' count. A block of scenes (SCENES instead of SCENE, e.g. the gcps.csv of "
            "pushbroom:simulateblock): every row names the scene it was measured in (SCENE_FIELD, by default the "
            "column 'scene') and is checked against that scene alone; one id may then be measured by cameras of one "
            "name in several scenes (camera P of two Pleiades products), and the layer keeps the field 'scene' "
            "that pushbroom:bundleadjust reads with SCENES.")
    CAMERA = CAMERA
    INPUT_FILE, INPUT = "INPUT_FILE", "INPUT"
    ID_FIELD, COL_FIELD, ROW_FIELD, X_FIELD, Y_FIELD = ID_FIELD, COL_FIELD, ROW_FIELD, "X_FIELD", "Y_FIELD"
    Z_FIELD, ROLE_FIELD, CAMERA_FIELD, SCENE_FIELD = "Z_FIELD", "ROLE_FIELD", CAMERA_FIELD, SCENE_FIELD
    GROUND_CRS, HEIGHT_SOURCE, CHECK_FRACTION, Z_DATUM = "GROUND_CRS", HEIGHT_SOURCE, CHECK_FRACTION, Z_DATUM
    SIGMA_PX, SIGMA_XY, SIGMA_Z, OUTPUT = SIGMA_PX, "SIGMA_XY", "SIGMA_Z", "OUTPUT"
    SIGMA_FIELDS = SIGMA_FIELDS
    # The inputs core errors name (core.errors.InputError.parameter) -> this algorithm's parameters.
    CORE_PARAMETERS = {"gcps.scene": SCENE_FIELD, "gcps.camera": CAMERA_FIELD}
    SCENE_OR_SCENES = ("check every point against one scene",
                       f"check each row against the scene of the block it names ({SCENE_FIELD})")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False, or_scenes=True)
        self.addParameter(camera())
        self.add_parameter(QgsProcessingParameterFile(self.INPUT_FILE, tr("GCP file (CSV or QGIS .points)"),
                                                      optional=True,
                                                      fileFilter="GCP files (*.csv *.txt *.points);;All files (*)"),
                  tr("Delimited text with a header row (delimiter , ; TAB or | detected; decimal commas accepted "
                     "with ; TAB |), or a QGIS Georeferencer .points file. The columns id, role and camera are read "
                     "under these names unless ID_FIELD, ROLE_FIELD or CAMERA_FIELD name others, so the simulator's "
                     "gcps.csv needs no field parameter for them. Give this or INPUT, not both."))
        self.add_parameter(QgsProcessingParameterFeatureSource(self.INPUT, tr("GCP point layer"),
                                                               [QgsProcessing.TypeVectorPoint], optional=True),
                  tr("Point layer whose geometry is the ground position (its own CRS) and whose fields hold the "
                     "image position (COL_FIELD, ROW_FIELD). Give this or INPUT_FILE, not both."))
        self.addParameter(id_field())
        self.addParameter(image_field(self.COL_FIELD))
        self.addParameter(image_field(self.ROW_FIELD))
        fields = ((self.X_FIELD, tr("Ground X / longitude field (CSV)"), "lon",
                   tr("Easting or longitude in GROUND_CRS.")),
                  (self.Y_FIELD, tr("Ground Y / latitude field (CSV)"), "lat",
                   tr("Northing or latitude in GROUND_CRS.")),
                  (self.Z_FIELD, tr("Height field"), "", tr("Height in metres (datum: Z_DATUM), used when "
                   "HEIGHT_SOURCE is z. Empty: the layer's point Z.")),
                  (self.ROLE_FIELD, tr("Role field"), "", tr("Values control/gcp or check/cp/checkpoint (empty cell "
                   "= control). Empty: the column/field 'role' when the input has one, else all points are control "
                   "points (see CHECK_FRACTION).")))
        for name, label, default, help_text in fields:
            self.add_parameter(QgsProcessingParameterString(name, label, optional=True, defaultValue=default),
                               help_text)
        self.addParameter(camera_field())
        self.addParameter(scene_field())
        self.add_parameter(QgsProcessingParameterCrs(self.GROUND_CRS, tr("Ground CRS (CSV and .points)"), optional=True,
                                            defaultValue="EPSG:4326"),
                  tr("CRS of the ground coordinates in a CSV, or of a .points file without a '#CRS:' line (the "
                     "file's own line wins). A layer brings its own CRS."))
        self.addParameter(height_source())
        self.addParameter(z_datum())
        add_dem_parameters(self)
        self.addParameter(check_fraction())
        self.addParameter(sigma_px())
        for name, label, default, help_text in (
                (self.SIGMA_XY, tr("Ground planimetric sigma (m)"), gcps.DEFAULT_SIGMA_XY,
                 tr("A-priori standard deviation of the ground east/north coordinates, in metres.")),
                (self.SIGMA_Z, tr("Ground height sigma (m)"), gcps.DEFAULT_SIGMA_Z,
                 tr("A-priori standard deviation of the ground height, in metres."))):
            self.add_parameter(QgsProcessingParameterNumber(name, label, QgsProcessingParameterNumber.Double, default,
                                                   minValue=0.0), help_text)
        for key in self.SIGMA_FIELDS:
            self.addParameter(sigma_field(key))
        out = QgsProcessingParameterVectorDestination(self.OUTPUT, tr("Ground control points"),
                                                      QgsProcessing.TypeVectorPoint)
        out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(out, tr("GeoPackage (.gpkg) point layer of the checked GCPs, styled so points with a "
                  "large a-priori residual (relative to the median) and points outside the image stand out."))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        dest = geopackage_output(self, parameters, context, self.OUTPUT, "gcps.gpkg", "GCP layers")
        camera_name = self.parameterAsString(parameters, self.CAMERA, context).strip() or None
        fraction = self.parameterAsDouble(parameters, self.CHECK_FRACTION, context)
        if block_given(self, parameters, context):
            paths = dict(zip(block_scene_names(scene_files(self, parameters, context)),
                             scene_files(self, parameters, context)))
            scenes = {name: load_scene_for(SCENES, path, feedback) for name, path in paths.items()}
            with core_log_to(feedback, observations.__name__):  # gcps, tables (cameras)
                table = self._read(parameters, context, block=list(paths))
                check_cancelled(feedback)
                feedback.setProgressText(f"checking {len(table)} rows against the scene each names")
                with self.core_errors():
                    table = check_against_block(table, scenes, paths, camera_name, fraction)
        else:
            scene_path = one_scene_file(self, parameters, context)
            scene = load_scene_for(SCENE, scene_path, feedback)
            with core_log_to(feedback, observations.__name__):  # gcps, tables (cameras)
                table = self._one_scene(self._read(parameters, context), feedback)
                check_cancelled(feedback)
                feedback.setProgressText(f"checking {len(table)} points against {scene_path}")
                table = core_call(gcps.check_against_scene, table, scene, scene_path, camera_name, fraction)
        with processing_errors(f"{self.OUTPUT}: "):
            gcps.write_gpkg(table, dest)
        self._report(table, feedback)
        style_output_on_load(context, dest, STYLES / "gcps.qml")
        feedback.setProgress(100)
        return {self.OUTPUT: dest}

    # --- reading --------------------------------------------------------------------------
    def _one_scene(self, table: gcps.GcpTable, feedback) -> gcps.GcpTable:
        """The table of a single SCENE; rows naming several scenes (the members of a strip, or the
        products of a block) are all checked against SCENE, which the log says."""
        named = sorted(set(table.block_scene) - {""})
        if len(named) > 1:
            feedback.pushWarning(f"{self.SCENE_FIELD}: the rows name {len(named)} scenes ({', '.join(named)}): all "
                                 f"are checked against {SCENE}, as the members of one strip; the products of a "
                                 f"block are checked each against its own scene with {SCENES}")
        return table

    def _read(self, parameters, context, block: list[str] | None = None) -> gcps.GcpTable:
        """The table of INPUT_FILE or INPUT; ``block``: the names of SCENES, which every row's scene
        must be one of (checked before anything else about the rows)."""
        path = self.parameterAsFile(parameters, self.INPUT_FILE, context)
        source = self.parameterAsSource(parameters, self.INPUT, context)
        if bool(path) == (source is not None):
            raise QgsProcessingException(f"give either {self.INPUT_FILE} (CSV or .points) or {self.INPUT} "
                                         f"(point layer), not {'both' if path else 'neither'}")
        features = source_features(self.INPUT, source) if source is not None else []  # an empty one said first
        crs_of_points = source.sourceCrs() if source is not None else \
            self.parameterAsCrs(parameters, self.GROUND_CRS, context)
        heights = heights_from_parameters(self, parameters, context, crs_of_points)
        sigmas = {f"sigma_{k}": self.parameterAsDouble(parameters, name, context)
                  for k, name in (("px", self.SIGMA_PX), ("xy", self.SIGMA_XY), ("z", self.SIGMA_Z))}
        crs = _crs_text(self.parameterAsCrs(parameters, self.GROUND_CRS, context))
        if source is not None:
            return self._from_layer(parameters, context, source, features, heights, sigmas, block)
        if path.lower().endswith(".points"):
            given = [name for name in (*self.SIGMA_FIELDS.values(), self.SCENE_FIELD)
                     if self.parameterAsString(parameters, name, context)]
            if given:
                raise QgsProcessingException(f"{given[0]}: QGIS .points files have no such field (no per-point "
                                             "sigma, no scene); leave it empty or import a CSV")
            return core_call(gcps.read_points_file, path, heights, crs, **sigmas)
        text = {name: self.parameterAsString(parameters, name, context).strip() or None
                for name in (self.ID_FIELD, self.COL_FIELD, self.ROW_FIELD, self.X_FIELD, self.Y_FIELD,
                             self.Z_FIELD, self.ROLE_FIELD, self.CAMERA_FIELD)}
        fields = {k: self.parameterAsString(parameters, name, context).strip() or None
                  for k, name in self.SIGMA_FIELDS.items()}
        mapping = gcps.CsvMapping(col=text[self.COL_FIELD], row=text[self.ROW_FIELD], x=text[self.X_FIELD],
                                  y=text[self.Y_FIELD], id=text[self.ID_FIELD], z=text[self.Z_FIELD],
                                  role=text[self.ROLE_FIELD], camera=text[self.CAMERA_FIELD],
                                  scene=self.parameterAsString(parameters, self.SCENE_FIELD, context).strip() or None,
                                  **fields)
        with self.core_errors():
            return gcps.read_csv(path, mapping, crs, heights, block, **sigmas)

    def _from_layer(self, parameters, context, source, features, heights, sigmas, block) -> gcps.GcpTable:
        """Arrays of the layer's features -> core.gcps.build_table (which checks them)."""
        require_points(self.INPUT, source)
        column = field_values(self, parameters, context, source, features)
        xyz = np.array([_point_xyz(f) for f in features], dtype=float)
        ids = column(self.ID_FIELD, False, "id") or [f.id() for f in features]
        for key, name in self.SIGMA_FIELDS.items():
            values = column(name, False)
            if values is not None:
                sigmas[key] = core_call(per_point_sigmas, attribute_texts(values), sigmas[key],
                                        self.parameterAsString(parameters, name, context).strip(),
                                        [str(i) for i in ids], f"{self.INPUT} layer", key)
        z = column(self.Z_FIELD, False)
        if z is None and QgsWkbTypes.hasZ(source.wkbType()):
            z = xyz[:, 2]
        with self.core_errors():
            return gcps.build_table([str(i) for i in ids], attribute_floats(column(self.COL_FIELD, True)),
                                    attribute_floats(column(self.ROW_FIELD, True)), xyz[:, 0], xyz[:, 1],
                                    crs=_crs_text(source.sourceCrs()), heights=heights,
                                    z=None if z is None else attribute_floats(z),
                                    role=attribute_texts(column(self.ROLE_FIELD, False, "role")),
                                    camera=attribute_texts(column(self.CAMERA_FIELD, False, "camera")),
                                    scene=attribute_texts(column(self.SCENE_FIELD, False, "scene")), block=block,
                                    source=f"{self.INPUT} layer", **sigmas)

    # --- report ---------------------------------------------------------------------------
    @staticmethod
    def _report(table: gcps.GcpTable, feedback) -> None:
        s = gcps.summary(table)
        feedback.pushInfo(f"{s['points']} points: {s['control']} control, {s['check']} check, "
                          f"{s['outside']} outside the image")
        if np.isfinite(s["median_px"]):
            feedback.pushInfo(f"a-priori residuals (points inside the image): median {s['median_px']:.2f} px "
                              f"({s['median_m']:.2f} m), max {s['max_px']:.2f} px ({s['max_m']:.2f} m)")


def _crs_text(crs: QgsCoordinateReferenceSystem) -> str | None:
    """A CRS string pyproj reads (the authority id, else WKT); None for an invalid CRS."""
    if not crs.isValid():
        return None
    return crs.authid() if crs.authid().upper().startswith("EPSG:") else \
        crs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED)


def _point_xyz(feature) -> tuple[float, float, float]:
    """(x, y, z) of a point feature; NaN for an empty geometry or a missing Z."""
    g = feature.geometry()
    if g.isNull() or g.isEmpty():
        return np.nan, np.nan, np.nan
    p = g.vertexAt(0)
    return p.x(), p.y(), p.z()
