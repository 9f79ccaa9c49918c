"""pushbroom:bundleadjust — self-calibrating bundle adjustment of a scene from its GCP layer:
the adjusted scene JSON, JSON and HTML reports, the GCP layer with residuals and flags, and
residual vectors."""
from __future__ import annotations

import math
from pathlib import Path

from qgis.core import (QgsProcessing, QgsProcessingException, QgsProcessingOutputFile,
                       QgsProcessingParameterEnum,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber,
                       QgsProcessingParameterString, QgsProcessingParameterVectorDestination,
                       QgsProcessingParameterVectorLayer)

from ...core import gcps
from ...core.adjust import AdjustmentSettings, adjust
from ...core.adjust.engine import check_inputs
from ...core.adjust.outputs import ground_residuals, write_adjusted_gcps, write_residual_vectors
from ...core.adjust.parameters import ParameterSet
from ...core.errors import PushbroomError
from ...core.files import Output, atomic_outputs
from ...core.scene_io import save_scene
from ...core.timebasis import TimeBasis
from ..common import (SCENE, STYLES, PushbroomAlgorithm, add_scene_parameters, check_cancelled, check_outputs,
                      core_call, feedback_callbacks, load_scene_for, processing_errors, style_output_on_load)

MODELS = ("polynomial", "lagrange", "spline")  # core.timebasis kinds, in the order of the enum
MODEL_LABELS = ("Polynomial (systematic-error compensation)", "Orientation images (4-point Lagrange)",
                "Piecewise polynomial (quadratic, continuous)")
ROBUST = ("none", "selection", "snooping")
ROBUST_LABELS = ("None", "Selection weights (posterior variances)", "Data snooping (Baarda)")
ARCSEC = math.pi / 648000.0


class BundleAdjustAlgorithm(PushbroomAlgorithm):
    ID = "bundleadjust"
    NAME = "Bundle adjustment"
    GROUP = "Adjustment"
    HELP = ("Self-calibrating bundle adjustment of a pushbroom scene (or strip) to its ground control points. "
            "Corrections to the measured orbit and attitude are estimated as polynomials, orientation images "
            "or piecewise polynomials in time; the onboard GPS and star trackers enter as weighted "
            "pseudo-observations. Interior parameters (CCD shifts and rotations, focal length, lens "
            "distortion, installation angles) can be estimated too. Parameter sets the GCPs cannot separate "
            "are detected and named, and one of each is fixed (or the run stops). Gross errors are found by "
            "selection weights or data snooping and flagged, never deleted. Check points are never used in "
            "the solution and give the accuracy before and after. Outputs: the adjusted scene JSON that every "
            "other algorithm reads as SCENE and, each when asked for, a JSON and an HTML report with plots, the "
            "GCP layer with the adjusted residuals and flags, and ground residual vectors.")
    GCPS = "GCPS"
    POSITION_MODEL, POSITION_ORDER, POSITION_INTERVAL, POSITION_SIGMA = \
        "POSITION_MODEL", "POSITION_ORDER", "POSITION_INTERVAL", "POSITION_SIGMA"
    ATTITUDE_MODEL, ATTITUDE_ORDER, ATTITUDE_INTERVAL, ATTITUDE_SIGMA = \
        "ATTITUDE_MODEL", "ATTITUDE_ORDER", "ATTITUDE_INTERVAL", "ATTITUDE_SIGMA"
    INTERIOR, GROUND, ROBUST, ALPHA, ON_SINGULAR, RESIDUAL_SCALE = \
        "INTERIOR", "GROUND", "ROBUST", "ALPHA", "ON_SINGULAR", "RESIDUAL_SCALE"
    OUTPUT_SCENE, OUTPUT_REPORT, OUTPUT_GCPS, OUTPUT_RESIDUALS = \
        "OUTPUT_SCENE", "OUTPUT_REPORT", "OUTPUT_GCPS", "OUTPUT_RESIDUALS"
    OUTPUT_REPORT_JSON = "OUTPUT_REPORT_JSON"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False)
        self.add_parameter(QgsProcessingParameterVectorLayer(self.GCPS, "Ground control points (GeoPackage)",
                                                    [QgsProcessing.TypeVectorPoint]),
                  "The GCP layer written by 'Import ground control points' (GeoPackage): image col/row, ground "
                  "position, role control/check, camera and sigmas of every point.")
        for block, default_order, default_sigma, unit, sigma_help in (
                ("POSITION", 1, 100.0, "m", "Accuracy of the onboard orbit (GPS), metres per axis: the position "
                 "corrections at the knots enter as pseudo-observations of 0 with this sigma. 0: none (only the GCPs "
                 "fix the position)."),
                ("ATTITUDE", 2, 0.0, "arcsec", "Accuracy of the onboard attitude (star trackers), arcseconds per "
                 "axis, as pseudo-observations of the attitude corrections. 0: none.")):
            what = block.lower()
            self.add_parameter(QgsProcessingParameterEnum(f"{block}_MODEL", f"{block.title()} correction model",
                                                 options=list(MODEL_LABELS), defaultValue=0),
                      f"How the {what} correction varies in time: a polynomial of order {block}_ORDER over the "
                      f"strip (systematic-error compensation, seed 000 eq. 1-2; order 2 without pseudo-observations "
                      f"is seed 002's quadratic model), orientation images every {block}_INTERVAL seconds with "
                      "4-point Lagrange interpolation (seed 000 eq. 3), or quadratic pieces between knots every "
                      f"{block}_INTERVAL seconds, continuous in value and slope (seed 001 eq. 9).")
            self.add_parameter(QgsProcessingParameterNumber(f"{block}_ORDER", f"{block.title()} polynomial order",
                                                   QgsProcessingParameterNumber.Integer, default_order, minValue=0,
                                                   maxValue=2),
                      "0: bias, 1: bias and drift, 2: also a quadratic term (polynomial model only).")
            self.add_parameter(QgsProcessingParameterNumber(f"{block}_INTERVAL", f"{block.title()} knot interval (s)",
                                                   QgsProcessingParameterNumber.Double, 20.0, minValue=0.01),
                      "Seconds between orientation images or knots (Lagrange and piecewise models). Shorter "
                      "intervals follow faster motion but let position and attitude trade off (seed 000 Fig. 7-11).")
            self.add_parameter(QgsProcessingParameterNumber(f"{block}_SIGMA", f"Onboard {what} sigma ({unit})",
                                                   QgsProcessingParameterNumber.Double, default_sigma, minValue=0.0),
                      sigma_help)
        self.add_parameter(QgsProcessingParameterString(self.INTERIOR, "Interior parameters to estimate", optional=True,
                                               defaultValue=""),
                  "Interior and installation parameters to estimate, comma-separated; every other one stays "
                  "at the scene's value. A name alone makes the parameter free; 'name=sigma' makes it weighted "
                  "(a pseudo-observation of 0 correction with that sigma, in the parameter's SI unit). Shell "
                  "wildcards match several names: * any text, ? one character. Names use the scene's chip and "
                  "camera names (CBERS-02B: camera HRC, chips HRC-1, HRC-2, HRC-3): {chip}.dx, .dy (CCD shift on "
                  "the focal plane, m) and .theta (CCD rotation, rad), seed 000 eq. 4; {chip}.ux0, .ux1, .uy0, "
                  ".uy1 (rad) for detectors given by look angles; {camera}.f (focal length correction, m), .dxp, "
                  ".dyp (principal point, m), .k1, .k2 (radial distortion), .p1, .p2 (decentring), .b1, .b2, .b3 "
                  "(affinity), seed 001 eq. 7; {camera}.roll, .pitch, .yaw (installation angles, rad; with several "
                  "cameras free them for all but the reference camera). Example for CBERS-02B: 'HRC-1.*, HRC-3.*' "
                  "(shifts and rotations of the left and right CCDs against the middle one); 'HRC-1.*, HRC-3.*, "
                  "HRC.f=1e-5' also estimates the focal length, weighted with 10 µm. Sets the GCPs cannot separate "
                  "from the trajectory are reported (see ON_SINGULAR). Empty: none (trajectory only).")
        self.add_parameter(QgsProcessingParameterEnum(self.GROUND, "GCP ground coordinates",
                                             options=["Weighted by their sigmas", "Fixed"], defaultValue=0),
                  "Weighted: the ground coordinates are unknowns with the GCPs' sigma_xy/sigma_z as pseudo-"
                  "observations (matched or map-derived points). Fixed: taken as exact (surveyed points).")
        self.add_parameter(QgsProcessingParameterEnum(self.ROBUST, "Gross error detection", options=list(ROBUST_LABELS),
                                             defaultValue=1),
                  "Selection weights down-weight observations whose normalised residual exceeds the critical "
                  "value (Li Deren's posterior-variance weights); data snooping removes them from the solution in "
                  "batches (Baarda). Either way the flagged points stay in the output layer with flagged = 1.")
        self.add_parameter(QgsProcessingParameterNumber(self.ALPHA, "Significance of the outlier test",
                                               QgsProcessingParameterNumber.Double, 0.001, minValue=1e-9, maxValue=0.2),
                  "Probability of flagging a good observation (0.001: |w| > 3.29).", advanced=True)
        self.add_parameter(QgsProcessingParameterEnum(self.ON_SINGULAR, "Non-determinable parameters",
                                             options=["Fix one of each set and continue", "Stop with their names"],
                                             defaultValue=0),
                  "What to do when the GCPs cannot separate some parameters (e.g. all three CBERS CCDs' shifts "
                  "and the attitude): fix one of each set (the middle CCD's, if involved) or stop.", advanced=True)
        self.add_parameter(QgsProcessingParameterNumber(self.RESIDUAL_SCALE, "Residual vector exaggeration",
                                               QgsProcessingParameterNumber.Double, 1000.0, minValue=1.0),
                  "Factor by which the ground residual vectors are drawn longer than they are.", advanced=True)
        self.add_parameter(QgsProcessingParameterFileDestination(self.OUTPUT_SCENE, "Adjusted scene",
                                                        fileFilter="Scene JSON (*.json)"),
                  "Scene JSON with the corrections, the parameters with sigmas and the settings; every algorithm "
                  "accepts it as SCENE.")
        self.add_parameter(QgsProcessingParameterFileDestination(self.OUTPUT_REPORT, "Report (HTML)",
                                                        fileFilter="HTML (*.html)", optional=True),
                  "Optional. A report to read: accuracy before/after, decisions, parameters, plots. The same "
                  "figures as JSON go beside it (same name, .json).")
        gcp_out = QgsProcessingParameterVectorDestination(self.OUTPUT_GCPS, "Adjusted GCPs",
                                                          QgsProcessing.TypeVectorPoint, optional=True)
        gcp_out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(gcp_out, "Optional. GeoPackage of the input points with the adjusted residuals (res_col, "
                  "res_row, res_px, res_m), normalised residuals w_col/w_row, redundancy, weight and flagged "
                  "(1 = gross error).")
        vec_out = QgsProcessingParameterVectorDestination(self.OUTPUT_RESIDUALS, "Residual vectors",
                                                          QgsProcessing.TypeVectorLine, optional=True)
        vec_out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(vec_out, "Optional. GeoPackage of lines from each GCP along its ground residual, "
                  "exaggerated RESIDUAL_SCALE times (res_m holds the true length).")
        self.addOutput(QgsProcessingOutputFile(self.OUTPUT_REPORT_JSON, "Report (JSON)"))


    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        from ...core.adjust.report import write_report_html, write_report_json
        outputs = {name: self._destination(parameters, context, name, suffix) for name, suffix in (
            (self.OUTPUT_SCENE, ".json"), (self.OUTPUT_REPORT, ".html"), (self.OUTPUT_GCPS, ".gpkg"),
            (self.OUTPUT_RESIDUALS, ".gpkg"))}  # '' for the optional ones not asked for
        report_html = outputs[self.OUTPUT_REPORT]
        report_json = str(Path(report_html).with_suffix(".json")) if report_html else ""
        check_outputs(self, parameters, context, {**{name: [path] for name, path in outputs.items()},
                                                  self.OUTPUT_REPORT: [report_html, Output(report_json,
                                                                                           "its JSON report")]})
        scene_path = self.parameterAsFile(parameters, SCENE, context)
        scene = load_scene_for(SCENE, scene_path)
        table, gcp_path, gcp_layer = self._gcps(parameters, context)
        settings = self._settings(parameters, context)
        scale = self.parameterAsDouble(parameters, self.RESIDUAL_SCALE, context)
        # Checks that name the parameter at fault before the (long) solution starts.
        core_call(settings.validate)
        with processing_errors(f"{self.GCPS}: "):
            check_inputs(scene, table, settings)
        self._check_interior(scene, settings.interior)
        feedback.pushInfo(f"{len(table)} points from {gcp_path}: {int((table.role == 'control').sum())} control, "
                          f"{int((table.role == 'check').sum())} check")
        progress, is_cancelled = feedback_callbacks(feedback)
        try:
            result = adjust(scene, table, settings, progress, is_cancelled)
        except PushbroomError as exc:
            raise QgsProcessingException(self._named(str(exc))) from None
        check_cancelled(feedback)
        feedback.setProgressText("writing the outputs")
        en = core_call(ground_residuals, result.scene, table, result.points["camera"])
        with processing_errors(), atomic_outputs() as files:  # every output or none
            with processing_errors(f"{self.OUTPUT_SCENE}: "):
                save_scene(result.scene, outputs[self.OUTPUT_SCENE], files)
            if report_html:
                with processing_errors(f"{self.OUTPUT_REPORT}: "):
                    write_report_json(result.report, report_json, files)
                    write_report_html(result.report, result.points, report_html,
                                      title=f"Bundle adjustment of {Path(scene_path).name}", files=files)
            if outputs[self.OUTPUT_GCPS]:
                with processing_errors(f"{self.OUTPUT_GCPS}: "):
                    write_adjusted_gcps(table, result.points, outputs[self.OUTPUT_GCPS], en=en,
                                        scene_path=outputs[self.OUTPUT_SCENE], source=gcp_path,
                                        source_layer=gcp_layer, files=files)
            if outputs[self.OUTPUT_RESIDUALS]:
                with processing_errors(f"{self.OUTPUT_RESIDUALS}: "):
                    write_residual_vectors(result.scene, table, result.points, outputs[self.OUTPUT_RESIDUALS],
                                           scale, en=en, files=files)
        style_output_on_load(context, outputs[self.OUTPUT_GCPS], STYLES / "adjusted_gcps.qml")
        style_output_on_load(context, outputs[self.OUTPUT_RESIDUALS], STYLES / "residual_vectors.qml")
        self._report(result.report, feedback)
        feedback.setProgress(100)
        return {**{name: path or None for name, path in outputs.items()}, self.OUTPUT_REPORT_JSON: report_json or None}

    # --- parameters -------------------------------------------------------------------------
    def _gcps(self, parameters, context) -> tuple[gcps.GcpTable, str, str | None]:
        """The GCP table, the GeoPackage's path and its layer name (None: the first layer)."""
        layer = self.parameterAsVectorLayer(parameters, self.GCPS, context)
        if layer is None:
            raise QgsProcessingException(f"{self.GCPS}: no GCP layer given")
        source = layer.source()
        path, _, options = source.partition("|")
        name = dict(o.split("=", 1) for o in options.split("|") if "=" in o).get("layername")
        if layer.providerType() != "ogr" or not path.lower().endswith(".gpkg"):
            raise QgsProcessingException(f"{self.GCPS}: {source} is not a GeoPackage; write the GCPs with 'Import "
                                         "ground control points' (pushbroom:importgcps) first")
        with processing_errors(f"{self.GCPS}: "):
            return gcps.read_gpkg(path, name), path, name

    def _check_interior(self, scene, interior: str) -> None:
        """INTERIOR's names and sigmas against the scene's parameters; the error lists the
        scene's cameras and CCD chips, whose names the patterns use."""
        t_min, t_max = scene.time_span()
        basis = TimeBasis.covering("polynomial", t_min, t_max, 0)
        try:
            ParameterSet(scene, basis, basis, interior)
        except PushbroomError as exc:
            names = "; ".join(f"camera {c.name} with chips " + ", ".join(ch.name or f"{c.name}-{k + 1}"
                                                                       for k, ch in enumerate(c.chips))
                              for c in scene.cameras)
            raise QgsProcessingException(f"{self.INTERIOR}: {exc}. This scene has {names}.") from None

    def _settings(self, parameters, context) -> AdjustmentSettings:
        number = lambda name: self.parameterAsDouble(parameters, name, context)  # noqa: E731
        position_sigma, attitude_sigma = number(self.POSITION_SIGMA), number(self.ATTITUDE_SIGMA)
        return AdjustmentSettings(
            position_model=MODELS[self.parameterAsEnum(parameters, self.POSITION_MODEL, context)],
            position_order=self.parameterAsInt(parameters, self.POSITION_ORDER, context),
            position_interval=number(self.POSITION_INTERVAL),
            attitude_model=MODELS[self.parameterAsEnum(parameters, self.ATTITUDE_MODEL, context)],
            attitude_order=self.parameterAsInt(parameters, self.ATTITUDE_ORDER, context),
            attitude_interval=number(self.ATTITUDE_INTERVAL),
            position_sigma=position_sigma or None, attitude_sigma=attitude_sigma * ARCSEC or None,
            interior=self.parameterAsString(parameters, self.INTERIOR, context),
            ground=("weighted", "fixed")[self.parameterAsEnum(parameters, self.GROUND, context)],
            robust=ROBUST[self.parameterAsEnum(parameters, self.ROBUST, context)],
            alpha=number(self.ALPHA),
            on_singular=("fix", "stop")[self.parameterAsEnum(parameters, self.ON_SINGULAR, context)])

    def _named(self, message: str) -> str:
        """A core error found while solving, prefixed with the parameter at fault where that is clear."""
        for start, name in (("too few GCPs", self.GCPS), ("the scene was adjusted with another", SCENE)):
            if message.startswith(start):
                return f"{name}: {message}"
        return message

    def _destination(self, parameters, context, name: str, suffix: str) -> str:
        path = self.output_path(parameters, context, name, name.lower() + suffix)
        if path and Path(path).suffix.lower() != suffix:
            raise QgsProcessingException(f"{name}: expected a {suffix} file (got {path})")
        return path

    @staticmethod
    def _report(rep: dict, feedback) -> None:
        for c in rep["high_correlations"]:
            if c["trajectory"]:
                feedback.pushWarning(f"{c['a']} and {c['b']} are correlated {c['r']:.4f}: the GCPs hardly separate "
                                     "them; give onboard sigmas (POSITION_SIGMA, ATTITUDE_SIGMA)")
        for d in rep["determinability"]:
            feedback.pushWarning(f"not determinable together from these GCPs: {', '.join(d['parameters'])}; "
                                 f"{d['fixed']} was fixed at its input value (ON_SINGULAR)")
        ctl = rep["control_residuals"]
        feedback.pushInfo(f"sigma0 {rep['sigma0']:.3f} ({'passes' if rep['sigma0_test']['passed'] else 'fails'} "
                          f"the 95 % test); control residuals RMSE col {ctl.get('rmse_col', float('nan')):.3f} px, "
                          f"row {ctl.get('rmse_row', float('nan')):.3f} px; {rep['robust']['flagged']} observations "
                          "flagged as gross errors")
        after = rep["check_points"]
        lines = [("before", rep["check_points_before"], after.get("points")), ("after", after, after.get("points"))]
        if after.get("blunders"):
            lines.append((f"after, without their {after['blunders']} blunders", after["without_blunders"],
                          after["points"] - after["blunders"]))
        for label, c, n in lines:
            if c and c.get("ground"):
                feedback.pushInfo(f"check points {label}: RMSE {c['image']['rmse']:.3f} px, "
                                  f"{c['ground']['rmse']:.2f} m (CE90 {c['ground']['ce90']:.2f} m) over {n} points")
