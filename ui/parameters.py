"""The plugin's parameter vocabulary: one definition per concept, shared by every algorithm.

A concept (the scene, its camera, the DEM and its datum, heights, check points, image
coordinate fields, the enumerations) has one parameter name, one description, one help
text, one default and, for enumerations, the same named values in the same order wherever
it appears. tests/qgis/test_vocabulary.py holds every algorithm of the provider to that.

Enumerations use static strings: scripts, graphical models and qgis_process pass the value
names (``DEM_DATUM=geoid``), never option numbers. QGIS 3.22 shows the names themselves in
the toolbox's drop-down lists (it has no separate labels for static-string values), so the
names are short words and every help text says what each name means.

User-visible texts go through :func:`tr` (one translation context for the whole plugin).
"""
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
CHECK_FRACTION, COL_FIELD, ROW_FIELD = "CHECK_FRACTION", "COL_FIELD", "ROW_FIELD"
POSITION_MODEL, ATTITUDE_MODEL = "POSITION_MODEL", "ATTITUDE_MODEL"
GROUND, ROBUST, ON_SINGULAR, RESAMPLING, PRESET = "GROUND", "ROBUST", "ON_SINGULAR", "RESAMPLING", "PRESET"
OUTPUT_SCENE = "OUTPUT_SCENE"
RPC_CORRECTION = "RPC_CORRECTION"
CAMERA_TRAJECTORY = "CAMERA_TRAJECTORY"
INPUTS = "INPUTS"
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
    """``text`` in the user's language, when a translation is installed (else unchanged)."""
    return QCoreApplication.translate(TR_CONTEXT, text)


# --- enumerations -------------------------------------------------------------------------
def enum_parameter(name: str, description: str, meanings: dict[str, str], default: str | None,
                   help_text: str, optional: bool = False) -> QgsProcessingParameterEnum:
    """An enumeration of named values (static strings); its help ends with what each name means."""
    if default is not None and default not in meanings:
        raise ValueError(f"{name}: default {default!r} is not one of {list(meanings)}")
    parameter = QgsProcessingParameterEnum(name, description, options=list(meanings), defaultValue=default,
                                           optional=optional, usesStaticStrings=True)
    values = "; ".join(f"<b>{value}</b>: {meaning}" for value, meaning in meanings.items())
    example = f"{name}={default or next(iter(meanings))}"
    parameter.setHelp(f"{help_text} " + tr("Values, by name (e.g. {example}; option numbers are refused)").format(
        example=example) + f": {values}.")
    return parameter


def _empty(value) -> bool:
    return value is None or value == "" or (isinstance(value, QVariant) and value.isNull())


def enum_refusal(definition: QgsProcessingParameterEnum, value) -> str | None:
    """Why ``value`` is not a value of enumeration ``definition`` (None when it is, or when it is
    not given). Option numbers are refused, never read as positions: the same number meant
    different values in different algorithms before the values had names."""
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
    """The value name given for enumeration ``name`` (its default when not given; None when it
    is optional and has none). Anything else stops the run with the value names."""
    definition = alg.parameterDefinition(name)
    value = parameters.get(name)
    if isinstance(value, QgsProperty):  # data-defined in a model: its evaluated text
        value = alg.parameterAsString(parameters, name, context)
    refusal = enum_refusal(definition, value)
    if refusal:
        raise QgsProcessingException(refusal)
    return definition.defaultValue() if _empty(value) else value


def datum_meanings(what: str) -> dict[str, str]:
    return {"geoid": tr("the EGM96 geoid, mean sea level") + f" ({what})",
            "ellipsoid": tr("the WGS84 ellipsoid (GNSS heights, EPSG:4979 layers such as the output of "
                            "'Image to ground')")}


def dem_datum() -> QgsProcessingParameterEnum:
    return enum_parameter(
        DEM_DATUM, tr("DEM height datum"),
        datum_meanings(tr("SRTM, Copernicus DEM, most national DEMs")), "geoid",
        tr("What the DEM's heights are measured from. Geoid heights are converted to ellipsoidal heights "
           "with PROJ's EGM96 grid."))


def z_datum() -> QgsProcessingParameterEnum:
    return enum_parameter(
        Z_DATUM, tr("Datum of the Z values"),
        datum_meanings(tr("levelled surveys, heights read from maps")), None,
        tr("What the points' Z values (point Z or Z_FIELD) are measured from (they differ by up to 106 m). "
           "Empty: what the points' CRS says (EPSG:4979: ellipsoid; EGM96 heights: geoid), else the run asks "
           "for it. Geoid heights are converted with PROJ's EGM96 grid."), optional=True)


def height_source() -> QgsProcessingParameterEnum:
    return enum_parameter(
        HEIGHT_SOURCE, tr("Heights from"),
        {"z": tr("the points' Z values (Z_FIELD, or the layer's point Z), in Z_DATUM"),
         "dem": tr("the DEM (in DEM_DATUM) sampled at each point"),
         "constant": tr("the constant ellipsoidal HEIGHT")}, "z",
        tr("Where the GCP heights come from. QGIS .points files hold no heights."))


def trajectory_model(name: str, what: str) -> QgsProcessingParameterEnum:
    """POSITION_MODEL or ATTITUDE_MODEL: the same values, default and help (``what``: position/attitude)."""
    block = name.split("_")[0]
    return enum_parameter(
        name, tr("{what} correction model").format(what=what.capitalize()),
        {"polynomial": tr("one polynomial of order {block}_ORDER over the strip (systematic-error "
                          "compensation, Zheng et al. 2015; order 2 without pseudo-observations is the quadratic "
                          "model of Tommaselli & Marcato Junior 2012)").format(block=block),
         "lagrange": tr("orientation images every {block}_INTERVAL seconds with 4-point Lagrange interpolation "
                        "(Zheng et al. 2015)").format(block=block),
         "spline": tr("quadratic pieces between knots every {block}_INTERVAL seconds, continuous in value and "
                      "slope (Zhang et al. 2015)").format(block=block)},
        "polynomial", tr("How the {what} correction varies in time.").format(what=what))


def ground_mode() -> QgsProcessingParameterEnum:
    return enum_parameter(
        GROUND, tr("GCP ground coordinates"),
        {"weighted": tr("unknowns with the GCPs' sigma_xy/sigma_z as pseudo-observations (matched or "
                        "map-derived points)"),
         "fixed": tr("taken as exact (surveyed points)")}, "weighted",
        tr("How the adjustment treats the ground coordinates of the control points."))


def robust_method() -> QgsProcessingParameterEnum:
    return enum_parameter(
        ROBUST, tr("Gross error detection"),
        {"none": tr("no detection"),
         "selection": tr("selection weights: observations whose normalised residual exceeds the critical value "
                         "are down-weighted (Li Deren's posterior-variance weights)"),
         "snooping": tr("data snooping: they are removed from the solution in batches (Baarda)")}, "selection",
        tr("How gross errors are found. Either way the flagged points stay in the output layer with "
           "flagged = 1."))


def rpc_correction() -> QgsProcessingParameterEnum:
    return enum_parameter(
        RPC_CORRECTION, tr("RPC scenes: image-space correction"),
        {"auto": tr("shift for a block with fewer than 3 control points (tie points alone), drift otherwise; "
                    "the log says which"),
         "shift": tr("a shift of columns and rows (2 parameters per image)"),
         "drift": tr("a shift and a drift along the rows, i.e. with time (4 parameters)"),
         "affine": tr("an affine correction of columns and rows (6 parameters)")}, "auto",
        tr("For RPC scenes (SCENE or the RPC products of SCENES): the bias compensation adjusted to the control "
           "(Grodecki & Dial 2003); ignored for rigorous scenes. Tie points alone do not determine the height "
           "tilt drift and affine let in (78 to 190 m over 5 km on simulated tri-stereos): hence auto."))


def camera_trajectory() -> QgsProcessingParameterEnum:
    return enum_parameter(
        CAMERA_TRAJECTORY, tr("Trajectory correction of several cameras"),
        {"shared": tr("one correction for all cameras of the platform; free the installation angles of all "
                      "but the reference camera in INTERIOR to let each camera's mounting differ (Zhang et al. "
                      "2024, Plans B-D by the attitude order 0, 1, 2)"),
         "per_camera": tr("a correction of its own for each camera, each with the onboard pseudo-observations "
                          "(Zhang et al. 2024, Plan A; installation angles are then absorbed and must stay "
                          "fixed)")}, "shared",
        tr("How the position and attitude corrections are shared among the cameras of a multi-camera scene "
           "(three-line cameras). A single-camera scene has one correction either way."))


def on_singular() -> QgsProcessingParameterEnum:
    return enum_parameter(
        ON_SINGULAR, tr("Non-determinable parameters"),
        {"fix": tr("fix one of each set (the middle CCD's, if involved) at its input value and continue"),
         "stop": tr("stop with their names")}, "fix",
        tr("What to do when the GCPs cannot separate some parameters (e.g. all three CBERS CCDs' shifts and "
           "the attitude)."))


def interior_selection() -> QgsProcessingParameterEnum:
    return enum_parameter(
        INTERIOR_SELECTION, tr("Interior parameter selection"),
        {"significant": tr("interior parameters the control cannot support (not significant, correlated, or "
                           "without information) are fixed at 0 and the block re-solved; weighted ones are kept, "
                           "held by their priors; self-calibration is kept only if an F-test favours it (docs "
                           "page)"),
         "keep": tr("estimate every INTERIOR parameter as given (with few GCPs a free set can overfit)")},
        "significant",
        tr("What to do with interior parameters the control at hand cannot support; the report lists the removed "
           "ones with the reason, the ones held by their priors with the reason, and the kept ones."))


def resampling() -> QgsProcessingParameterEnum:
    return enum_parameter(
        RESAMPLING, tr("Resampling"),
        {"nearest": tr("nearest neighbour"), "bilinear": tr("bilinear"), "cubic": tr("cubic spline")},
        "bilinear", tr("How raw pixel values are interpolated."))


def preset() -> QgsProcessingParameterEnum:
    return enum_parameter(PRESET, tr("Sensor preset"), {n: PRESETS[n].description for n in PRESET_NAMES},
                          DEFAULT_PRESET, tr("The simulated sensor and orbit."))


# --- shared plain parameters --------------------------------------------------------------
def scene(optional: bool = False) -> QgsProcessingParameterFile:
    """SCENE; optional in the algorithms that take a block's SCENES instead, its label then saying that
    one of the two is needed (QGIS marks both '[optional]')."""
    label = tr("Scene (or give Scenes of the block)") if optional else tr("Scene (metadata, RPC or scene JSON)")
    parameter = QgsProcessingParameterFile(SCENE, label, extension="",
                                           fileFilter="Scene files (*.json *.xml *.XML *.txt *.TXT *.rpb *.RPB *.tif "
                                                      "*.ntf *.jp2);;All files (*)", optional=optional)
    parameter.setHelp(tr("The sensor model of the scene: a scene JSON (of the simulator or an adjustment), vendor "
                         "metadata (DIMAP v2 DIM_*.XML, Maxar *.XML), or an RPC alone: an image with RPC metadata, "
                         "<name>_RPC.TXT, <name>.RPB or DIMAP RPC_*.XML (docs/rpc-scenes.md).")
                      + (" " + tr("Give SCENE or SCENES: one of them.") if optional else ""))
    return parameter


def scenes() -> QgsProcessingParameterMultipleLayers:
    """SCENES: the scene files of a block (matchtiepoints, importgcps, bundleadjust), the alternative to SCENE."""
    parameter = QgsProcessingParameterMultipleLayers(SCENES, tr("Scenes of the block (or give one Scene)"),
                                                     QgsProcessing.TypeFile, optional=True)
    parameter.setHelp(tr("Several scenes as one block, any files the plugin reads as a scene. A scene's name is its "
                         "file's stem (without _RPC), or its folder's for onboard_scene.json, true_scene.json, "
                         "adjusted_scene.json; observations name their scene in a field 'scene'. Give SCENE or "
                         "SCENES: one of them."))
    return parameter


def output_scene(optional: bool = False) -> QgsProcessingParameterFileDestination:
    """OUTPUT_SCENE; optional in the algorithms that take a block's SCENES instead of SCENE (a block
    writes its scenes elsewhere); a run of one scene then writes it to a temporary file."""
    parameter = QgsProcessingParameterFileDestination(OUTPUT_SCENE, tr("Output scene"),
                                                      fileFilter="Scene JSON (*.json)", optional=optional)
    parameter.setHelp(tr("Scene JSON of the sensor model this algorithm makes (the adjusted scene, or the virtual "
                         "camera of a sensor-corrected image; the algorithm's help says which); every algorithm "
                         "accepts it as SCENE."))
    return parameter


def camera() -> QgsProcessingParameterString:
    parameter = QgsProcessingParameterString(CAMERA, tr("Camera (name or index)"), optional=True, defaultValue="")
    parameter.setHelp(tr("For scenes with several cameras (three-line and multi-CCD sensors): the camera's name "
                         "(e.g. NAD, FWD, BWD) or its 0-based index. Empty: the first camera; when importing "
                         "GCPs, each point's CAMERA_FIELD value (or the scene's only camera)."))
    return parameter


def value_given(value) -> bool:
    """Whether a parameter value holds something: not None, NULL, '' nor an empty list."""
    if isinstance(value, (list, tuple)):
        return any(value_given(v) for v in value)
    return value is not None and value != NULL and value != ""


class RasterInput(QgsProcessingParameterRasterLayer):
    """A raster layer parameter (the toolbox shows it as QGIS's own) whose check of a value never loads
    the raster as a QGIS layer. QGIS's check, which the toolbox, processing.run and qgis_process run
    before an algorithm, loads a raster given by path as a layer; QGIS computes the statistics of a
    layer it loads, and GDAL writes them beside the file (<file>.aux.xml) or into it (a VRT) when the
    layer is dropped. Here a value is acceptable when it is given (or the parameter is optional); the
    algorithm checks the file itself with GDAL, naming the parameter (ui.inputs.raster_refusal)."""

    def clone(self):
        return _cloned(self, RasterInput(self.name(), self.description(), self.defaultValue()))

    def checkValueIsAcceptable(self, value, context=None):  # noqa: N802 (QGIS API name)
        return value_given(value) or bool(self.flags() & QgsProcessingParameterDefinition.FlagOptional)


class RasterInputs(QgsProcessingParameterMultipleLayers):
    """Several rasters (QGIS's multiple-layer parameter of rasters), checked as :class:`RasterInput` is."""

    def __init__(self, name: str, description: str, optional: bool = False):
        super().__init__(name, description, QgsProcessing.TypeRaster, optional=optional)

    def clone(self):
        return _cloned(self, RasterInputs(self.name(), self.description()))

    def checkValueIsAcceptable(self, value, context=None):  # noqa: N802 (QGIS API name)
        return value_given(value) or bool(self.flags() & QgsProcessingParameterDefinition.FlagOptional)


def _cloned(parameter, copy):
    """``copy`` (a new parameter of ``parameter``'s class, name and description) given its flags, help
    and metadata."""
    copy.setFlags(parameter.flags())
    copy.setHelp(parameter.help())
    copy.setMetadata(parameter.metadata())
    return copy


def dem() -> RasterInput:
    parameter = RasterInput(DEM, tr("Digital elevation model"), optional=True)
    parameter.setHelp(tr("Raster of terrain heights in metres (datum: DEM_DATUM), in any CRS, covering the whole "
                         "area the algorithm works on. Leave empty to use the constant HEIGHT instead."))
    return parameter


def height() -> QgsProcessingParameterNumber:
    parameter = QgsProcessingParameterNumber(HEIGHT, tr("Constant ellipsoidal height (m) instead of a DEM"),
                                             type=QgsProcessingParameterNumber.Double, defaultValue=0.0)
    parameter.setHelp(tr("Height in metres above the WGS84 ellipsoid of a flat terrain, used when no DEM is given "
                         "(or HEIGHT_SOURCE is constant). Ellipsoidal height = sea-level height + geoid "
                         "undulation (-106 m to +85 m over the Earth)."))
    return parameter


def camera_images() -> RasterInputs:
    """INPUTS: one raw image per camera of a scene (orthorectify ALL_CAMERAS, matchtiepoints)."""
    parameter = RasterInputs(INPUTS, tr("Raw images, one per camera"), optional=True)
    parameter.setHelp(tr("One raw image per camera of the scene, in the scene's camera order (the log shows which "
                         "image goes to which camera); each must have its camera's size. Used by orthorectify "
                         "with ALL_CAMERAS."))
    return parameter


def matching_parameters() -> list[QgsProcessingParameterNumber]:
    """The image matching settings (core.matching.MatchSettings): SPACING, N_POINTS, WINDOW,
    MIN_CORRELATION, SEARCH_RANGE, FINE_RADIUS."""
    number = QgsProcessingParameterNumber
    out = []
    for name, label, kind, default, lo, hi, help_text in (
            (SPACING, tr("Grid spacing (px)"), number.Double, 200.0, 8.0, 1e5,
             tr("Distance in raw image pixels between the grid points matched (used when N_POINTS is 0).")),
            (N_POINTS, tr("Number of points (0: use the spacing)"), number.Integer, 0, 0, 10_000_000,
             tr("About this many grid points, evenly spread over the image; 0: SPACING decides.")),
            (WINDOW, tr("Matching window (px)"), number.Integer, 31, 9, 257,
             tr("Side of the square window correlated and fitted by least squares, in raw image pixels (odd). "
                "Larger: more texture per window (sand, fields), slower. 31 suits 0.5 m Pleiades and 2-5 m "
                "images alike.")),
            (MIN_CORRELATION, tr("Quality threshold (correlation)"), number.Double, 0.6, 0.05, 0.99,
             tr("Matches whose correlation peak is below this value are rejected (clouds, water, changed "
                "land cover). The second-to-first peak ratio must also be below 0.85.")),
            (SEARCH_RANGE, tr("Search range (m)"), number.Double, 1000.0, 10.0, 50_000.0,
             tr("Largest onboard position error looked for, in metres on the ground (for tie points: between "
                "the images). Searched on a coarse copy first, so a large range costs little; one beyond the "
                "image is clipped to it (the log says so). If no consistent match is found, try twice the "
                "expected error.")),
            (FINE_RADIUS, tr("Fine search radius (px)"), number.Integer, 8, 2, 64,
             tr("How far, in raw image pixels, each window is searched around the offset the coarse levels "
                "predict (a clear peak within 3 px is taken first). Larger: follows relief the DEM lacks, but "
                "meets more repeated texture; smaller: faster."))):
        parameter = number(name, label, kind, default, minValue=lo, maxValue=hi)
        parameter.setHelp(help_text)
        out.append(parameter)
    return out


def check_fraction() -> QgsProcessingParameterNumber:
    parameter = QgsProcessingParameterNumber(CHECK_FRACTION, tr("Share of points made check points"),
                                             QgsProcessingParameterNumber.Double, 0.0, minValue=0.0, maxValue=1.0)
    parameter.setHelp(tr("0 to 1: this share of the points gets the role 'check'. Check points are never used "
                         "in an adjustment; they measure its accuracy."))
    return parameter


def image_field(name: str) -> QgsProcessingParameterString:
    """COL_FIELD or ROW_FIELD: the name of a table's field (CSV column) holding image coordinates."""
    axis, default, edge = ("column", "col", "left") if name == COL_FIELD else ("row", "row", "top")
    parameter = QgsProcessingParameterString(name, tr("Image {axis} field").format(axis=axis), optional=True,
                                             defaultValue=default)
    parameter.setHelp(tr("Name of the field (CSV column) holding the image {axis} in pixels, GDAL convention "
                         "(0 = {edge} edge of the image). Default: '{default}'.").format(axis=axis, edge=edge,
                                                                                         default=default))
    return parameter


ID_FIELD, CAMERA_FIELD, SCENE_FIELD, SIGMA_PX = "ID_FIELD", "CAMERA_FIELD", "SCENE_FIELD", "SIGMA_PX"
SIGMA_FIELDS = {"sigma_px": "SIGMA_PX_FIELD", "sigma_xy": "SIGMA_XY_FIELD", "sigma_z": "SIGMA_Z_FIELD"}


def id_field() -> QgsProcessingParameterString:
    """ID_FIELD of the point imports: rows with one id are one ground point."""
    parameter = QgsProcessingParameterString(ID_FIELD, tr("Point id field"), optional=True, defaultValue="")
    parameter.setHelp(tr("Point id; rows with the same id are one ground point seen in several cameras. Empty: "
                         "the column/field 'id' when the input has one, else the line number (CSV) or feature id "
                         "(layer), every row a point of its own (tie points need ids: an error)."))
    return parameter


def camera_field() -> QgsProcessingParameterString:
    """CAMERA_FIELD of the point imports."""
    parameter = QgsProcessingParameterString(CAMERA_FIELD, tr("Camera field"), optional=True, defaultValue="")
    parameter.setHelp(tr("Camera name (or 0-based index) of each row, for scenes with several cameras (e.g. "
                         "CAMERA_FIELD=camera). Empty: the column/field 'camera' when the input has one, else the "
                         "scene's only camera. A CAMERA parameter, where the algorithm has one, overrides it."))
    return parameter


def scene_field() -> QgsProcessingParameterString:
    """SCENE_FIELD of the point imports: the product of a block each row was measured in."""
    parameter = QgsProcessingParameterString(SCENE_FIELD, tr("Scene field"), optional=True, defaultValue="")
    parameter.setHelp(tr("Name of the scene each row was measured in, for the scenes of a block (SCENES of "
                         "pushbroom:bundleadjust: the scene file's stem, or its folder's name for the layout "
                         "pushbroom:simulateblock writes), or of a strip (kept for reference). Empty: the "
                         "column/field 'scene' when the input has one, else none."))
    return parameter


def sigma_px() -> QgsProcessingParameterNumber:
    """SIGMA_PX: the image measurement sigma of imported points."""
    parameter = QgsProcessingParameterNumber(SIGMA_PX, tr("Image measurement sigma (px)"),
                                             QgsProcessingParameterNumber.Double, DEFAULT_SIGMA_PX, minValue=0.0)
    parameter.setHelp(tr("A-priori standard deviation of the measured col/row, in pixels."))
    return parameter


def sigma_field(key: str) -> QgsProcessingParameterString:
    """SIGMA_PX_FIELD, SIGMA_XY_FIELD or SIGMA_Z_FIELD (``key`` sigma_px, sigma_xy, sigma_z): per-point sigmas."""
    what, unit = {"sigma_px": ("image measurement sigma", "px"), "sigma_xy": ("ground planimetric sigma", "m"),
                  "sigma_z": ("ground height sigma", "m")}[key]
    parameter = QgsProcessingParameterString(SIGMA_FIELDS[key], tr("Per-point {} field ({})").format(what, unit),
                                             optional=True, defaultValue="")
    parameter.setHelp(tr("Field (CSV column or layer field) holding each point's {0} in {1}, so that surveyed "
                         "and map-digitised points can be mixed; an empty cell takes {2}. Values must be > 0. "
                         "Empty: every point takes {2}.").format(what, unit, key.replace("sigma_", "SIGMA_").upper()))
    return parameter


def image_lines() -> QgsProcessingParameterVectorLayer:
    """IMAGE_LINES: image lines digitised on a raw image (pixel frame)."""
    parameter = QgsProcessingParameterVectorLayer("IMAGE_LINES", tr("Image lines"), [QgsProcessing.TypeVectorLine])
    parameter.setHelp(tr("The image lines digitised on the raw image (layer image_lines of 'Prepare digitising'): "
                         "x = column, y = -row, fields line_id, camera, sigma_px (M values: per-vertex sigmas)."))
    return parameter


# --- a block adjustment's own parameters (bundleadjust with SCENES) ------------------------
SCENE_SIGMAS, BLOCK_FOLDER, WRITE_RPCS = "SCENE_SIGMAS", "OUTPUT_FOLDER", "WRITE_RPCS"


def helped(parameter, text: str, advanced: bool = False):
    """``parameter`` with its help ``text`` (and flagged advanced)."""
    parameter.setHelp(text)
    if advanced:
        parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
    return parameter


def scene_sigmas() -> QgsProcessingParameterMatrix:
    """SCENE_SIGMAS: each block scene's own sigmas, a matrix of any number of rows (read by
    :func:`core.adjust.scenesigmas.read_scene_sigmas`); optional."""
    return helped(QgsProcessingParameterMatrix(SCENE_SIGMAS, tr("Per-scene onboard / vendor sigmas (block)"),
                                               numberRows=0, hasFixedNumberRows=False, headers=list(SIGMA_HEADERS),
                                               optional=True),
                  tr("Optional, with SCENES: each scene's own onboard or vendor accuracy. One row per scene: scene (as "
                     "SCENES names it), position_sigma_m, attitude_sigma_arcsec, rpc_sigma_px; an empty cell keeps "
                     "the global value, which must be given. qgis_process: SCENE_SIGMAS=old,,60, (docs page)."))


def block_folder() -> QgsProcessingParameterFolderDestination:
    """OUTPUT_FOLDER of a block adjustment (its files: :mod:`core.runs.blockadjust`)."""
    return helped(QgsProcessingParameterFolderDestination(BLOCK_FOLDER, tr("Block output folder"), optional=True),
                  tr("With SCENES: the folder (created if missing) the block's outputs go to, every file or none: "
                     "<name>_adjusted.json per scene, block_report.html/.json, adjusted_gcps.gpkg, "
                     "adjusted_tie_points.gpkg, line_residuals.gpkg (docs page). Files of these names are replaced. "
                     "Empty: a temporary folder."))


def write_rpcs() -> QgsProcessingParameterBoolean:
    """WRITE_RPCS: a refined RPC of each image of a block; optional, so that graphical models saved
    before it need no value for it."""
    return helped(QgsProcessingParameterBoolean(WRITE_RPCS, tr("Refined RPC of each image (block)"),
                                                defaultValue=False, optional=True),
                  tr("With SCENES: also write into OUTPUT_FOLDER an RPC00B fitted to each adjusted rigorous scene, "
                     "<name>_RPC.TXT (<name>_<CAMERA>_RPC.TXT for several cameras) with its fit check (.json), and "
                     "an RPC product's refined RPC; copy it beside the image as <image>_RPC.TXT."), advanced=True)


def trajectory_parameters(block: str, what: str, order: int, sigma: float | None, unit: str, sigma_help: str,
                          sigma_range: tuple[float, float]) -> list:
    """bundleadjust's parameters of the trajectory correction ``block`` ('POSITION', 'ATTITUDE'): its
    model, polynomial order, knot interval and onboard sigma (default ``sigma``, plausible from
    ``sigma_range`` (low, high) in ``unit``)."""
    title, number = tr(what).capitalize(), QgsProcessingParameterNumber
    low, high = sigma_range
    return [trajectory_model(f"{block}_MODEL", tr(what)),
            helped(number(f"{block}_ORDER", tr("{what} polynomial order").format(what=title), number.Integer, order,
                          minValue=0, maxValue=2),
                   tr("0: bias, 1: bias and drift, 2: also a quadratic term (polynomial model only).")),
            helped(number(f"{block}_INTERVAL", tr("{what} knot interval (s)").format(what=title), number.Double, 20.0,
                          minValue=0.01),
                   tr("Seconds between orientation images or knots (lagrange and spline models). Shorter intervals "
                      "follow faster motion but let position and attitude trade off (Zheng et al. 2015, Fig. 7-11).")),
            helped(number(f"{block}_SIGMA", tr("Onboard {what} sigma ({unit})").format(what=tr(what), unit=unit),
                          number.Double, sigma, optional=True, minValue=0.0, maxValue=high),
                   tr(sigma_help) + " " + tr("Otherwise from {low:g} to {high:g} {unit}.").format(low=low, high=high,
                                                                                               unit=unit))]


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
    report = helped(QgsProcessingParameterFileDestination("OUTPUT_REPORT", tr("Report (HTML)"),
                                                          fileFilter="HTML (*.html)", optional=True),
                    tr("Optional. A report to read: accuracy before/after, decisions, parameters, plots. The same "
                       "figures as JSON go beside it (same name, .json)."))
    rpc = helped(QgsProcessingParameterFileDestination("OUTPUT_RPC", tr("Refined RPC (RPC scenes)"),
                                                       fileFilter="RPC text (*_RPC.TXT)", optional=True),
                 tr("Optional, for a SCENE given by its RPC: the RPC with the adjusted correction in it, as "
                    "<image>_RPC.TXT, which GDAL and QGIS read for <image>.tif beside it (a correction mixing rows "
                    "and columns refitted, about 1e-5 px)."))
    layers = []
    for name, label, kind, text in (
            ("OUTPUT_GCPS", "Adjusted GCPs", QgsProcessing.TypeVectorPoint, "Optional. GeoPackage of the input points "
             "with the adjusted residuals (res_col, res_row, res_px, res_m), normalised residuals w_col/w_row, "
             "redundancy, weight and flagged (1 = gross error)."),
            ("OUTPUT_RESIDUALS", "Residual vectors", QgsProcessing.TypeVectorLine, "Optional. GeoPackage of lines "
             "from each GCP along its ground residual, exaggerated RESIDUAL_SCALE times (res_m holds the true "
             "length)."),
            ("OUTPUT_TIE_POINTS", "Adjusted tie points", QgsProcessing.TypeVectorPoint, "Optional, with TIE_POINTS. "
             "Point layer (EPSG:4979), one feature per tie observation at its point's adjusted ground position: id, "
             "camera, col, row, res_col, res_row, res_px (px), w_col, w_row, weight, flagged (1 = gross error)."),
            ("OUTPUT_LINE_RESIDUALS", "Line residuals", QgsProcessing.TypeVectorPoint, "GeoPackage with layer "
             "line_points (each image-line point at its adjusted ground, its image residual and across-line offset "
             "in m) and ground_lines (per line RMS and max across-line offset, flagged = 1 for lines named wrong).")):
        layer = QgsProcessingParameterVectorDestination(name, tr(label), kind, optional=True,
                                                        createByDefault=name != "OUTPUT_LINE_RESIDUALS")
        layer.setSupportsNonFileBasedOutput(False)
        layers.append(helped(layer, tr(text)))
    return [report, *layers[:3], rpc, layers[3]]
