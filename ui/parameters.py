"""The plugin's parameter vocabulary: a concept has one name, description, default and (enumerations)
value names in one order wherever it appears (tests/qgis/test_vocabulary.py); help: docs/parameters.md.
Enumerations take value names (``DEM_DATUM=geoid``), never option numbers."""
from __future__ import annotations

from qgis.core import (NULL, QgsProcessing, QgsProcessingException, QgsProcessingParameterBoolean,
                       QgsProcessingParameterDefinition, QgsProcessingParameterEnum, QgsProcessingParameterFile,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterFolderDestination,
                       QgsProcessingParameterMatrix, QgsProcessingParameterMultipleLayers,
                       QgsProcessingParameterNumber, QgsProcessingParameterRasterLayer, QgsProcessingParameterString,
                       QgsProcessingParameterVectorDestination, QgsProcessingParameterVectorLayer, QgsProperty)
from qgis.PyQt.QtCore import QCoreApplication, QVariant

from ..core.adjust.scenesigmas import HEADERS as SIGMA_HEADERS
from ..core.observations.gcps import DEFAULT_SIGMA_PX
from ..core.products.resampling import RESAMPLING as CORE_RESAMPLING
from ..simulation.presets import PRESETS
from ..core.model.timebasis import KINDS

TR_CONTEXT = "PushbroomAdjust"

SCENE, SCENES, CAMERA = "SCENE", "SCENES", "CAMERA"
DEM, DEM_DATUM, Z_DATUM, HEIGHT, HEIGHT_SOURCE = "DEM", "DEM_DATUM", "Z_DATUM", "HEIGHT", "HEIGHT_SOURCE"
TIE_HEIGHT_SIGMA = "TIE_HEIGHT_SIGMA"
CHECK_FRACTION, COL_FIELD, ROW_FIELD = "CHECK_FRACTION", "COL_FIELD", "ROW_FIELD"
POSITION_MODEL, ATTITUDE_MODEL = "POSITION_MODEL", "ATTITUDE_MODEL"
GROUND, ROBUST, ON_SINGULAR, RESAMPLING, PRESET = "GROUND", "ROBUST", "ON_SINGULAR", "RESAMPLING", "PRESET"
OUTPUT_SCENE = "OUTPUT_SCENE"
RPC_CORRECTION = "RPC_CORRECTION"
CAMERA_TRAJECTORY = "CAMERA_TRAJECTORY"
INPUTS = "INPUTS"
SCHEDULER = "SCHEDULER"
SPACING, N_POINTS, WINDOW, MIN_CORRELATION, SEARCH_RANGE, FINE_RADIUS = \
    "SPACING", "N_POINTS", "WINDOW", "MIN_CORRELATION", "SEARCH_RANGE", "FINE_RADIUS"

# Value names of the enumerations, in the order the drop-down lists show them; they are the
# core's own names (core.dem datums, core.observations.tables.Heights.source, core.model.timebasis.KINDS, ...).
DATUMS = ("geoid", "ellipsoid")
HEIGHT_SOURCES = ("z", "dem", "constant")
TRAJECTORY_MODELS = KINDS  # polynomial, lagrange, spline
GROUND_MODES = ("weighted", "fixed")
ROBUST_METHODS = ("none", "selection", "snooping")
ON_SINGULAR_ACTIONS = ("fix", "stop")
INTERIOR_SELECTION = "INTERIOR_SELECTION"
RESAMPLINGS = tuple(CORE_RESAMPLING)  # nearest, bilinear, cubic
PRESET_NAMES = tuple(PRESETS)
DEFAULT_PRESET = "cbers02b_hrc"


def tr(text: str) -> str:
    """``text`` in the user's language, when a translation is installed (one context for the whole plugin)."""
    return QCoreApplication.translate(TR_CONTEXT, text)


# --- enumerations -------------------------------------------------------------------------
def enum_parameter(name: str, description: str, values, default: str | None,
                   optional: bool = False) -> QgsProcessingParameterEnum:
    """An enumeration of the static strings ``values`` (a dict: its keys) in the drop-down's order; QGIS 3.22
    shows the names themselves (no labels), so they are short words."""
    if default is not None and default not in values:
        raise ValueError(f"{name}: default {default!r} is not one of {list(values)}")
    return QgsProcessingParameterEnum(name, description, options=list(values), defaultValue=default,
                                      optional=optional, usesStaticStrings=True)


def _empty(value) -> bool:
    return value is None or value == "" or (isinstance(value, QVariant) and value.isNull())


def enum_refusal(definition: QgsProcessingParameterEnum, value) -> str | None:
    """Why ``value`` is not a value of enumeration ``definition`` (None when it is, or is not given)."""
    if _empty(value) or isinstance(value, QgsProperty) or (isinstance(value, str) and value in definition.options()):
        return None
    name, names = definition.name(), ", ".join(definition.options())
    if isinstance(value, (list, tuple)):
        return f"{name}: takes one value, not a list ({value!r}); give one of: {names}"
    text = str(value).strip()
    if isinstance(value, (int, float)) or text.lstrip("+-").replace(".", "", 1).isdigit():
        return (f"{name}: {text} is an option number; option numbers are not accepted (the same number meant "
                f"different values in different algorithms), give the value's name, one of: {names}")
    if text.lower() in definition.options():
        return f"{name}: {text!r} is not a value; names are lower case: did you mean {text.lower()!r}? ({names})"
    return f"{name}: {text!r} is not a value of this parameter; give one of: {names}"


def enum_value(alg, parameters: dict, name: str, context) -> str | None:
    """The value name given for enumeration ``name``, else its default (None); else the run stops."""
    definition = alg.parameterDefinition(name)
    value = parameters.get(name)
    if isinstance(value, QgsProperty):  # data-defined in a model: its evaluated text
        value = alg.parameterAsString(parameters, name, context)
    refusal = enum_refusal(definition, value)
    if refusal:
        raise QgsProcessingException(refusal)
    return definition.defaultValue() if _empty(value) else value


def dem_datum() -> QgsProcessingParameterEnum:
    """DEM_DATUM, optional with its default: graphical models and scripts written before an algorithm
    took a DEM (bundleadjust's reference DEM) stay valid."""
    return enum_parameter(DEM_DATUM, tr("DEM height datum"), DATUMS, "geoid", optional=True)


def z_datum() -> QgsProcessingParameterEnum:
    return enum_parameter(Z_DATUM, tr("Datum of the Z values"), DATUMS, None, optional=True)


def height_source() -> QgsProcessingParameterEnum:
    return enum_parameter(HEIGHT_SOURCE, tr("Heights from"), HEIGHT_SOURCES, "z")


def trajectory_model(name: str, what: str) -> QgsProcessingParameterEnum:
    """POSITION_MODEL or ATTITUDE_MODEL (``what``: position/attitude)."""
    return enum_parameter(name, tr("{what} correction model").format(what=what.capitalize()), TRAJECTORY_MODELS,
                          "polynomial")


def ground_mode() -> QgsProcessingParameterEnum:
    return enum_parameter(GROUND, tr("GCP ground coordinates"), GROUND_MODES, "weighted")


def robust_method() -> QgsProcessingParameterEnum:
    return enum_parameter(ROBUST, tr("Gross error detection"), ROBUST_METHODS, "selection")


def rpc_correction() -> QgsProcessingParameterEnum:
    return enum_parameter(RPC_CORRECTION, tr("RPC scenes: image-space correction"),
                          ("auto", "shift", "drift", "affine"), "auto")


def camera_trajectory() -> QgsProcessingParameterEnum:
    return enum_parameter(CAMERA_TRAJECTORY, tr("Trajectory correction of several cameras"),
                          ("shared", "per_camera"), "shared")


def on_singular() -> QgsProcessingParameterEnum:
    return enum_parameter(ON_SINGULAR, tr("Non-determinable parameters"), ON_SINGULAR_ACTIONS, "fix")


def interior_selection() -> QgsProcessingParameterEnum:
    return enum_parameter(INTERIOR_SELECTION, tr("Interior parameter selection"), ("significant", "keep"),
                          "significant")


def resampling() -> QgsProcessingParameterEnum:
    return enum_parameter(RESAMPLING, tr("Resampling"), RESAMPLINGS, "bilinear")


def preset() -> QgsProcessingParameterEnum:
    return enum_parameter(PRESET, tr("Sensor preset"), PRESET_NAMES, DEFAULT_PRESET)


# --- shared plain parameters (their help: docs/parameters.md) ------------------------------
def scene(optional: bool = False) -> QgsProcessingParameterFile:
    """SCENE; optional in the algorithms that take a block's SCENES instead, its label then saying that
    one of the two is needed (QGIS marks both '[optional]')."""
    label = tr("Scene (or give Scenes of the block)") if optional else tr("Scene (metadata, RPC or scene JSON)")
    return QgsProcessingParameterFile(SCENE, label, extension="",
                                      fileFilter="Scene files (*.json *.xml *.XML *.txt *.TXT *.rpb *.RPB *.tif "
                                                 "*.ntf *.jp2);;All files (*)", optional=optional)


def scenes() -> QgsProcessingParameterMultipleLayers:
    """SCENES: the scene files of a block (matchtiepoints, importgcps, bundleadjust), the alternative to SCENE."""
    return QgsProcessingParameterMultipleLayers(SCENES, tr("Scenes of the block (or give one Scene)"),
                                                QgsProcessing.TypeFile, optional=True)


def output_scene(optional: bool = False) -> QgsProcessingParameterFileDestination:
    """OUTPUT_SCENE; optional in the algorithms that take a block's SCENES instead of SCENE (a block
    writes its scenes elsewhere); a run of one scene then writes it to a temporary file."""
    return QgsProcessingParameterFileDestination(OUTPUT_SCENE, tr("Output scene"), fileFilter="Scene JSON (*.json)",
                                                 optional=optional)


def scheduler() -> QgsProcessingParameterString:
    """SCHEDULER: the address of a Dask distributed scheduler; empty: this machine's cores (orthorectify,
    matchtiepoints)."""
    return QgsProcessingParameterString(SCHEDULER, tr("Dask scheduler address"), optional=True)


def camera() -> QgsProcessingParameterString:
    return QgsProcessingParameterString(CAMERA, tr("Camera (name or index)"), optional=True, defaultValue="")


def value_given(value) -> bool:
    """Whether a parameter value holds something: not None, NULL, '' nor an empty list."""
    if isinstance(value, (list, tuple)):
        return any(value_given(v) for v in value)
    return value is not None and value != NULL and value != ""


class CheckedByGdal:
    """A raster parameter not loaded as a QGIS layer to check a value (QGIS's check would, and GDAL then
    writes the statistics QGIS computes beside the file or into a VRT): a value given is acceptable; the
    algorithm checks the file with GDAL (ui.inputs.raster_refusal)."""

    def clone(self):
        copy = type(self)(self.name(), self.description())
        copy.setDefaultValue(self.defaultValue())
        copy.setFlags(self.flags())
        copy.setHelp(self.help())
        copy.setMetadata(self.metadata())
        return copy

    def checkValueIsAcceptable(self, value, context=None):  # noqa: N802 (QGIS API name)
        return value_given(value) or bool(self.flags() & QgsProcessingParameterDefinition.FlagOptional)


class RasterInput(CheckedByGdal, QgsProcessingParameterRasterLayer):
    """A raster layer parameter (the toolbox shows QGIS's own), checked by GDAL."""


class RasterInputs(CheckedByGdal, QgsProcessingParameterMultipleLayers):
    """Several rasters (QGIS's multiple-layer parameter of rasters), checked by GDAL."""

    def __init__(self, name: str, description: str, optional: bool = False):
        super().__init__(name, description, QgsProcessing.TypeRaster, optional=optional)


def dem() -> RasterInput:
    return RasterInput(DEM, tr("Digital elevation model"), optional=True)


def tie_height_sigma() -> QgsProcessingParameterNumber:
    """TIE_HEIGHT_SIGMA: the stated accuracy (m) of the DEM that holds the tie points' heights."""
    return QgsProcessingParameterNumber(TIE_HEIGHT_SIGMA, tr("Tie point heights: the DEM's stated accuracy (m)"),
                                        QgsProcessingParameterNumber.Double, None, optional=True, minValue=0.0,
                                        maxValue=1000.0)


def height() -> QgsProcessingParameterNumber:
    return QgsProcessingParameterNumber(HEIGHT, tr("Constant ellipsoidal height (m) instead of a DEM"),
                                        type=QgsProcessingParameterNumber.Double, defaultValue=0.0)


def camera_images() -> RasterInputs:
    """INPUTS: one raw image per camera of a scene (orthorectify ALL_CAMERAS, matchtiepoints)."""
    return RasterInputs(INPUTS, tr("Raw images, one per camera"), optional=True)


def matching_parameters() -> list[QgsProcessingParameterNumber]:
    """The image matching settings (core.matching.MatchSettings): SPACING, N_POINTS, WINDOW,
    MIN_CORRELATION, SEARCH_RANGE, FINE_RADIUS."""
    number = QgsProcessingParameterNumber
    return [number(name, label, kind, default, minValue=lo, maxValue=hi) for name, label, kind, default, lo, hi in (
        (SPACING, tr("Grid spacing (px)"), number.Double, 200.0, 8.0, 1e5),
        (N_POINTS, tr("Number of points (0: use the spacing)"), number.Integer, 0, 0, 10_000_000),
        (WINDOW, tr("Matching window (px)"), number.Integer, 31, 9, 257),
        (MIN_CORRELATION, tr("Quality threshold (correlation)"), number.Double, 0.6, 0.05, 0.99),
        (SEARCH_RANGE, tr("Search range (m)"), number.Double, 1000.0, 10.0, 50_000.0),
        (FINE_RADIUS, tr("Fine search radius (px)"), number.Integer, 8, 2, 64))]


def check_fraction() -> QgsProcessingParameterNumber:
    return QgsProcessingParameterNumber(CHECK_FRACTION, tr("Share of points made check points"),
                                        QgsProcessingParameterNumber.Double, 0.0, minValue=0.0, maxValue=1.0)


def image_field(name: str) -> QgsProcessingParameterString:
    """COL_FIELD or ROW_FIELD: the name of a table's field (CSV column) holding image coordinates."""
    axis, default = ("column", "col") if name == COL_FIELD else ("row", "row")
    return QgsProcessingParameterString(name, tr("Image {axis} field").format(axis=axis), optional=True,
                                        defaultValue=default)


ID_FIELD, CAMERA_FIELD, SCENE_FIELD, SIGMA_PX = "ID_FIELD", "CAMERA_FIELD", "SCENE_FIELD", "SIGMA_PX"
SIGMA_FIELDS = {"sigma_px": "SIGMA_PX_FIELD", "sigma_xy": "SIGMA_XY_FIELD", "sigma_z": "SIGMA_Z_FIELD"}


# The optional fields of the point imports, empty by default: name -> label.
FIELD_LABELS = {ID_FIELD: "Point id field", CAMERA_FIELD: "Camera field", SCENE_FIELD: "Scene field",
                "SIGMA_PX_FIELD": "Per-point image measurement sigma field (px)",
                "SIGMA_XY_FIELD": "Per-point ground planimetric sigma field (m)",
                "SIGMA_Z_FIELD": "Per-point ground height sigma field (m)"}


def point_field(name: str) -> QgsProcessingParameterString:
    """A field of the point imports (FIELD_LABELS: ID_FIELD, CAMERA_FIELD, SCENE_FIELD, SIGMA_*_FIELD)."""
    return QgsProcessingParameterString(name, tr(FIELD_LABELS[name]), optional=True, defaultValue="")


def sigma_px() -> QgsProcessingParameterNumber:
    return QgsProcessingParameterNumber(SIGMA_PX, tr("Image measurement sigma (px)"),
                                        QgsProcessingParameterNumber.Double, DEFAULT_SIGMA_PX, minValue=0.0)


def image_lines() -> QgsProcessingParameterVectorLayer:
    """IMAGE_LINES: image lines digitised on a raw image (pixel frame)."""
    return QgsProcessingParameterVectorLayer("IMAGE_LINES", tr("Image lines"), [QgsProcessing.TypeVectorLine])


def file_layer(name: str, label: str, kind, **options) -> QgsProcessingParameterVectorDestination:
    """A vector output the core writes as a file (a GeoPackage): no memory layer, no database table."""
    layer = QgsProcessingParameterVectorDestination(name, label, kind, **options)
    layer.setSupportsNonFileBasedOutput(False)
    return layer


# --- a block adjustment's own parameters (bundleadjust with SCENES) ------------------------
SCENE_SIGMAS, BLOCK_FOLDER, WRITE_RPCS = "SCENE_SIGMAS", "OUTPUT_FOLDER", "WRITE_RPCS"
UNITS = {"POSITION": "m", "ATTITUDE": "arcsec"}  # of the onboard sigmas


def scene_sigmas() -> QgsProcessingParameterMatrix:
    """SCENE_SIGMAS: each block scene's own sigmas, any number of rows (core.adjust.scenesigmas)."""
    return QgsProcessingParameterMatrix(SCENE_SIGMAS, tr("Per-scene onboard / vendor sigmas (block)"), numberRows=0,
                                        hasFixedNumberRows=False, headers=list(SIGMA_HEADERS), optional=True)


def block_folder() -> QgsProcessingParameterFolderDestination:
    """OUTPUT_FOLDER of a block adjustment (its files: :mod:`core.runs.blockadjust`)."""
    return QgsProcessingParameterFolderDestination(BLOCK_FOLDER, tr("Block output folder"), optional=True)


def write_rpcs() -> QgsProcessingParameterBoolean:
    """WRITE_RPCS; optional so that graphical models saved before it need no value for it."""
    parameter = QgsProcessingParameterBoolean(WRITE_RPCS, tr("Refined RPC of each image (block)"), defaultValue=False,
                                              optional=True)
    parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
    return parameter


def trajectory_parameters(block: str, what: str, order: int, sigma: float | None, high: float) -> list:
    """bundleadjust's parameters of the trajectory correction ``block`` ('POSITION', 'ATTITUDE'): its
    model, polynomial order, knot interval and onboard sigma (default ``sigma``, at most ``high``)."""
    title, number = tr(what).capitalize(), QgsProcessingParameterNumber
    return [trajectory_model(f"{block}_MODEL", tr(what)),
            number(f"{block}_ORDER", tr("{what} polynomial order").format(what=title), number.Integer, order,
                   minValue=0, maxValue=2),
            number(f"{block}_INTERVAL", tr("{what} knot interval (s)").format(what=title), number.Double, 20.0,
                   minValue=0.01),
            number(f"{block}_SIGMA", tr("Onboard {what} sigma ({unit})").format(what=tr(what), unit=UNITS[block]),
                   number.Double, sigma, optional=True, minValue=0.0, maxValue=high)]


def matrix_texts(alg, parameters, name: str, context) -> tuple[str, ...]:
    """The values of matrix parameter ``name`` as stripped texts, row by row (() when not given: a NULL,
    an empty text or list); a whole number's text without '.0' (a scene named '2021' read back as 2021.0)."""
    if name not in parameters:
        return ()
    values = [int(v) if isinstance(v, float) and v.is_integer() else v
              for v in alg.parameterAsMatrix(parameters, name, context)]
    texts = tuple("" if v is None or v == NULL else str(v).strip() for v in values)
    return texts if any(texts) else ()


def adjustment_outputs() -> list:
    """bundleadjust's outputs of one scene after OUTPUT_SCENE, in order: the report, the adjusted GCP
    layer, the residual vectors, the adjusted tie points, the refined RPC and the line residuals."""
    report = QgsProcessingParameterFileDestination("OUTPUT_REPORT", tr("Report (HTML)"), fileFilter="HTML (*.html)",
                                                   optional=True)
    rpc = QgsProcessingParameterFileDestination("OUTPUT_RPC", tr("Refined RPC (RPC scenes)"),
                                                fileFilter="RPC text (*_RPC.TXT)", optional=True)
    layers = [file_layer(name, tr(label), kind, optional=True, createByDefault=name != "OUTPUT_LINE_RESIDUALS")
              for name, label, kind in (("OUTPUT_GCPS", "Adjusted GCPs", QgsProcessing.TypeVectorPoint),
                                        ("OUTPUT_RESIDUALS", "Residual vectors", QgsProcessing.TypeVectorLine),
                                        ("OUTPUT_TIE_POINTS", "Adjusted tie points", QgsProcessing.TypeVectorPoint),
                                        ("OUTPUT_LINE_RESIDUALS", "Line residuals", QgsProcessing.TypeVectorPoint))]
    return [report, *layers[:3], rpc, layers[3]]
