"""pushbroom:bundleadjust — self-calibrating bundle adjustment of a scene (or, with SCENES, a block of
scenes) from its GCPs, tie points and control lines: the parameters of :mod:`core.runs.bundleadjust`."""
from __future__ import annotations

import numpy as np
from qgis.core import (QgsProcessing, QgsProcessingException, QgsProcessingOutputFile,
                       QgsProcessingOutputMultipleLayers, QgsProcessingParameterBoolean,
                       QgsProcessingParameterNumber,
                       QgsProcessingParameterString, QgsProcessingParameterVectorLayer, QgsProcessingUtils)

from ...core.adjust.settings import ONBOARD_SIGMAS, AdjustmentSettings
from ...core.observations import tiepoints
from ...core.rotations import ARCSEC
from ...core.runs import adjustinputs as names, bundleadjust as use_case
from ..inputs import (add_scene_parameters, attribute_floats, attribute_texts, block_scene_names, ogr_source,
                      raster_file, scene_or_block, split_ogr_source)
from ..outputs import STYLES, files_in_use, style_output_on_load
from ..parameters import (ATTITUDE_MODEL, BLOCK_FOLDER, CAMERA_TRAJECTORY, DEM, DEM_DATUM, GROUND, INTERIOR_SELECTION,
                          ON_SINGULAR, POSITION_MODEL, ROBUST, RPC_CORRECTION, SCENE, SCENE_SIGMAS, SCENES,
                          TIE_HEIGHT_SIGMA, WRITE_RPCS, adjustment_outputs, block_folder, camera_trajectory, dem,
                          dem_datum, enum_value, ground_mode, interior_selection, matrix_texts, on_singular,
                          output_scene, robust_method, rpc_correction, scene_sigmas, tie_height_sigma, tr,
                          trajectory_parameters, write_rpcs)
from .base import PushbroomAlgorithm

Number = QgsProcessingParameterNumber
STYLED = {names.OUTPUT_GCPS: "adjusted_gcps.qml", names.OUTPUT_RESIDUALS: "residual_vectors.qml",
          names.OUTPUT_TIE_POINTS: "adjusted_tie_points.qml", names.OUTPUT_LINE_RESIDUALS: "control_lines.qml"}


class BundleAdjustAlgorithm(PushbroomAlgorithm):
    ID = "bundleadjust"
    NAME = "Bundle adjustment"
    GROUP, GROUP_ID = "Adjustment", "adjustment"
    GCPS, TIE_POINTS, LINES, INTERIOR, ALPHA, RPC_SIGMA, RESIDUAL_SCALE = \
        "GCPS", "TIE_POINTS", "LINES", "INTERIOR", "ALPHA", "RPC_SIGMA", "RESIDUAL_SCALE"
    VARIANCE_COMPONENTS, MAX_ROBUST_PASSES, OUTPUT_REPORT_JSON = \
        "VARIANCE_COMPONENTS", "MAX_ROBUST_PASSES", names.OUTPUT_REPORT_JSON
    SCENE_OR_SCENES = ("adjust one scene (its cameras, or the scenes of one strip)",
                       "adjust several scenes together as a block, each observation naming its scene")
    # The inputs core errors name (core.errors.InputError.parameter) -> this algorithm's parameters.
    CORE_PARAMETERS = {
        names.GCPS: GCPS, names.TIES: TIE_POINTS, names.LINES: LINES, "scene": SCENE, names.SCENES: SCENES,
        **{f"settings.{key}_{part}": f"{key.upper()}_{part.upper()}" for key in ("position", "attitude")
           for part in ("model", "order", "interval", "sigma")},
        "settings.camera_trajectory": CAMERA_TRAJECTORY, names.INTERIOR: INTERIOR,
        "settings.interior_selection": INTERIOR_SELECTION, "settings.ground": GROUND, "settings.robust": ROBUST,
        "settings.alpha": ALPHA, "settings.variance_components": VARIANCE_COMPONENTS,
        "settings.max_robust_iterations": MAX_ROBUST_PASSES, "settings.on_singular": ON_SINGULAR,
        "settings.rpc_correction": RPC_CORRECTION, "settings.rpc_sigma": RPC_SIGMA, names.SCENE_SIGMAS: SCENE_SIGMAS,
        "settings.dem": DEM, "settings.dem_datum": DEM_DATUM, "settings.tie_height_sigma": TIE_HEIGHT_SIGMA,
        **{name: name for name in (*names.ONE_SCENE_SUFFIXES, BLOCK_FOLDER, WRITE_RPCS)}}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        # The order of work: the observations, the model, the control, the robust settings, the outputs.
        # Every parameter's help is in docs/algorithms/bundleadjust.md (ui.help).
        add_scene_parameters(self, with_camera=False, or_scenes=True)
        for name, label, kind in ((self.GCPS, "Ground control points (GeoPackage)", QgsProcessing.TypeVectorPoint),
                                  (self.TIE_POINTS, "Tie points", QgsProcessing.TypeVector),
                                  (self.LINES, "Control lines (GeoPackage)", QgsProcessing.TypeVectorLine)):
            self.addParameter(QgsProcessingParameterVectorLayer(name, tr(label), [kind], optional=True))
        self.addParameter(QgsProcessingParameterString(self.INTERIOR, tr("Interior parameters to estimate"),
                                                       optional=True, defaultValue=""))
        for block, what, order, sigma, scale in (("POSITION", "position", 1, 100.0, 1.0),
                                                 ("ATTITUDE", "attitude", 2, None, ARCSEC)):
            high = ONBOARD_SIGMAS[f"{block.lower()}_sigma"][1] / scale
            for parameter in trajectory_parameters(block, what, order, sigma, high):
                self.addParameter(parameter)
        self.addParameter(interior_selection())
        self.addParameter(camera_trajectory())
        self.addParameter(rpc_correction())
        self.addParameter(Number(self.RPC_SIGMA, tr("RPC scenes: stated accuracy (px)"), Number.Double, None,
                                 optional=True, minValue=0.0, maxValue=1e5))
        for parameter in (scene_sigmas(), dem(), dem_datum(), tie_height_sigma(), ground_mode(), robust_method()):
            self.addParameter(parameter)
        self.addParameter(Number(self.ALPHA, tr("Significance of the outlier test"), Number.Double, 0.001,
                                 minValue=1e-9, maxValue=0.2))
        self.addParameter(QgsProcessingParameterBoolean(self.VARIANCE_COMPONENTS, tr("Estimate variance components"),
                                                        defaultValue=True))
        self.addParameter(Number(self.MAX_ROBUST_PASSES, tr("Robust passes at most"), Number.Integer, 12, minValue=1,
                                 maxValue=100))
        self.addParameter(on_singular())
        self.addParameter(output_scene(optional=True))  # optional: SCENES writes OUTPUT_FOLDER
        for parameter in adjustment_outputs():
            self.addParameter(parameter)
        self.addOutput(QgsProcessingOutputFile(self.OUTPUT_REPORT_JSON, tr("Report (JSON)")))
        self.addParameter(Number(self.RESIDUAL_SCALE, tr("Residual vector exaggeration"), Number.Double, 1000.0,
                                 minValue=1.0, maxValue=1e6))
        for parameter in (block_folder(), write_rpcs()):
            self.addParameter(parameter)
        self.addOutput(QgsProcessingOutputMultipleLayers(names.ADJUSTED_SCENES, tr("Adjusted scenes of the block "
                                                                                  "(scene JSON, SCENES order)")))
        self.show_only(SCENE, SCENES, self.GCPS, self.TIE_POINTS, self.LINES, self.INTERIOR)

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        scene, paths = scene_or_block(self, parameters, context, feedback)
        block = bool(paths)
        ties, tie_rows = self._ties(parameters, context)
        lines = self.parameterAsVectorLayer(parameters, self.LINES, context)
        number = lambda name: self.parameterAsDouble(parameters, name, context)  # noqa: E731
        result = self.run_core(use_case.run, names.AdjustRequest(
            scene, dict(zip(block_scene_names(paths), paths)) if block else None,
            self._layer(parameters, context, self.GCPS),
            ties, tie_rows, ogr_source(self.LINES, lines, "control lines")[0] if lines is not None else "",
            self.adjustment_settings(parameters, context), matrix_texts(self, parameters, SCENE_SIGMAS, context),
            self._outputs(parameters, context, block),
            (self.parameterAsFileOutput(parameters, BLOCK_FOLDER, context)
             or QgsProcessingUtils.generateTempFilename("block_adjustment")) if block else
            self.user_destination(parameters, context, BLOCK_FOLDER),
            self.parameterAsBoolean(parameters, WRITE_RPCS, context), number(self.RESIDUAL_SCALE),
            files_in_use(self, parameters, context)), feedback)
        for name, style in STYLED.items():
            style_output_on_load(context, result.files[name] or "", STYLES / style)
        return result.files

    def _layer(self, parameters, context, name: str) -> names.LayerFile | None:
        layer = self.parameterAsVectorLayer(parameters, name, context)
        return None if layer is None else names.LayerFile(*split_ogr_source(layer.source()), layer.source())

    def _ties(self, parameters, context) -> tuple:
        """(TIE_POINTS's layer file, or its rows read from the features of a layer without a file)."""
        if parameters.get(self.TIE_POINTS) in (None, ""):
            return None, None
        layer = self.parameterAsVectorLayer(parameters, self.TIE_POINTS, context)
        if layer is None:
            raise QgsProcessingException(f"{self.TIE_POINTS}: {parameters[self.TIE_POINTS]} is not a vector layer "
                                         "or table; give the layer written by 'Import tie points'")
        if layer.providerType() == "ogr":
            return self._layer(parameters, context, self.TIE_POINTS), None
        fields = layer.fields().names()
        missing = [f for f in ("id", "camera", "col", "row") if f not in fields]
        if missing:
            raise QgsProcessingException(f"{self.TIE_POINTS}: {layer.source()} lacks tie-point field(s) "
                                         f"{', '.join(missing)} (fields: {', '.join(fields)})")
        features = list(layer.getFeatures())
        column = {f: [feature[f] for feature in features] if f in fields else None
                  for f in ("id", "camera", "col", "row", "sigma_px", "scene")}
        sigma = attribute_floats(column["sigma_px"] or [None] * len(features))
        with self.core_errors(self.TIE_POINTS):
            return names.LayerFile("", None, layer.source()), tiepoints.build_table(
                attribute_texts(column["id"]), attribute_texts(column["camera"]), attribute_floats(column["col"]),
                attribute_floats(column["row"]), scene=attribute_texts(column["scene"]), source=layer.source(),
                sigma_px=np.where(np.isfinite(sigma), sigma, tiepoints.DEFAULT_SIGMA_PX))

    def _outputs(self, parameters, context, block: bool) -> dict:
        """One scene's outputs ('' not asked; OUTPUT_SCENE a temporary file then); with SCENES those
        the user gave (a temporary file is not given)."""
        if block:
            return {name: self.user_destination(parameters, context, name) for name in names.ONE_SCENE_SUFFIXES}
        out = {name: self.output_path(parameters, context, name, name.lower() + suffix)
               for name, suffix in names.ONE_SCENE_SUFFIXES.items()}
        scene = names.OUTPUT_SCENE  # optional only for a block: one scene's adjusted model is always written
        return {**out, scene: out[scene] or QgsProcessingUtils.generateTempFilename("output_scene.json")}

    def adjustment_settings(self, parameters, context) -> AdjustmentSettings:
        number = lambda name: self.parameterAsDouble(parameters, name, context)  # noqa: E731
        values = {key: enum_value(self, parameters, name, context) for key, name in (
            ("position_model", POSITION_MODEL), ("attitude_model", ATTITUDE_MODEL), ("ground", GROUND),
            ("camera_trajectory", CAMERA_TRAJECTORY), ("interior_selection", INTERIOR_SELECTION), ("robust", ROBUST),
            ("on_singular", ON_SINGULAR), ("rpc_correction", RPC_CORRECTION))}
        values.update({key: self.parameterAsInt(parameters, name, context) for key, name in (
            ("position_order", "POSITION_ORDER"), ("attitude_order", "ATTITUDE_ORDER"),
            ("max_robust_iterations", self.MAX_ROBUST_PASSES))})
        return AdjustmentSettings(
            **values, position_interval=number("POSITION_INTERVAL"), attitude_interval=number("ATTITUDE_INTERVAL"),
            position_sigma=number("POSITION_SIGMA") or None, attitude_sigma=number("ATTITUDE_SIGMA") * ARCSEC or None,
            interior=self.parameterAsString(parameters, self.INTERIOR, context), alpha=number(self.ALPHA),
            variance_components=self.parameterAsBoolean(parameters, self.VARIANCE_COMPONENTS, context),
            rpc_sigma=number(self.RPC_SIGMA) or None, dem=raster_file(self, parameters, DEM, context),
            dem_datum=enum_value(self, parameters, DEM_DATUM, context),
            tie_height_sigma=number(TIE_HEIGHT_SIGMA) or None)
