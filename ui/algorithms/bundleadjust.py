"""pushbroom:bundleadjust — self-calibrating bundle adjustment of a scene from its GCP layer
and tie points: the adjusted scene JSON, JSON and HTML reports, the GCP and tie-point layers
with residuals and flags, and residual vectors."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from qgis.core import (QgsProcessing, QgsProcessingException, QgsProcessingOutputFile,
                       QgsProcessingParameterBoolean,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber,
                       QgsProcessingParameterString, QgsProcessingParameterVectorDestination,
                       QgsProcessingParameterVectorLayer, QgsProcessingUtils)

from ...core.adjust import AdjustmentSettings, adjust
from ...core.adjust.checks import check_inputs
from ...core.adjust.linepoints import ControlLines
from ...core.adjust.outputs import (ground_residuals, write_adjusted_gcps, write_adjusted_tie_points,
                                    write_line_residuals, write_residual_vectors)
from ...core.adjust.parameters import ParameterSet
from ...core.adjust.report import log_lines, write_report_json
from ...core.adjust.report_html import write_report_html
from ...core.adjust.settings import ONBOARD_SIGMAS
from ...core.errors import PushbroomError
from ...core.files import Output, atomic_outputs
from ...core.formats.rpcfiles import write_rpc
from ...core.formats.scene_json import save_scene
from ...core.model.rpcscene import RpcScene
from ...core.model.timebasis import TimeBasis
from ...core.observations import gcps, tiepoints
from ...core.observations.lines import read_ground_lines, read_image_lines
from ...core.products.rpcfit import refined_rpc
from ...core.rotations import ARCSEC
from ..blockadjust import (ADJUSTED_SCENES, OUTPUT_FOLDER, WRITE_RPCS, add_block_parameters, read_tie_layer,
                          run_block, user_destination)
from ..blockmatch import block_given, one_scene_file
from ..feedback import check_cancelled, core_call, core_log_to, feedback_callbacks, processing_errors
from ..inputs import add_scene_parameters, load_scene_for, ogr_source, split_ogr_source
from ..outputs import STYLES, check_outputs, style_output_on_load
from ..scenesigmas import SCENE_SIGMAS, refuse_for_one_scene, scene_sigmas_parameter
from ..parameters import (ATTITUDE_MODEL, CAMERA_TRAJECTORY, GROUND, INTERIOR_SELECTION, ON_SINGULAR, POSITION_MODEL,
                          ROBUST, RPC_CORRECTION, SCENE, SCENES, camera_trajectory, enum_value, ground_mode,
                          interior_selection, on_singular, output_scene, robust_method, rpc_correction, tr,
                          trajectory_model)
from .base import PushbroomAlgorithm


class BundleAdjustAlgorithm(PushbroomAlgorithm):
    ID = "bundleadjust"
    NAME = "Bundle adjustment"
    GROUP, GROUP_ID = "Adjustment", "adjustment"
    HELP = ("Self-calibrating bundle adjustment of a pushbroom scene (or strip) to its ground control points. "
            "Corrections to the measured orbit and attitude are estimated as polynomials, orientation images "
            "or piecewise polynomials in time; the onboard GPS and star trackers enter as weighted "
            "pseudo-observations. Interior parameters (CCD shifts and rotations, focal length, lens "
            "distortion, installation angles) can be estimated too. Parameter sets the GCPs cannot separate "
            "are detected and named, and one of each is fixed (or the run stops). Gross errors are found by "
            "selection weights or data snooping and flagged, never deleted. Check points are never used in "
            "the solution and give the accuracy before and after. Outputs: the adjusted scene JSON that every "
            "other algorithm reads as SCENE and, each when asked for, a JSON and an HTML report with plots, the "
            "GCP layer with the adjusted residuals and flags, and ground residual vectors. A SCENE given by its RPC "
            "only (an image with RPC metadata, _RPC.TXT, .RPB, DIMAP RPC_*.XML) is adjusted by an image-space "
            "correction instead (RPC_CORRECTION, Grodecki & Dial 2003), with the same statistics and outputs, "
            "and can be written as a refined RPC (OUTPUT_RPC). "
            "Three-line cameras (Zhang et al. 2024): Plan A, a trajectory correction per camera, is "
            "CAMERA_TRAJECTORY=per_camera with ATTITUDE_ORDER=1 and no installation angles in INTERIOR; Plans B, C "
            "and D, one attitude correction shared by all cameras plus the installation angles of the others "
            "against the reference (nadir) camera, are CAMERA_TRAJECTORY=shared, INTERIOR='FWD.roll, FWD.pitch, "
            "FWD.yaw, BWD.roll, BWD.pitch, BWD.yaw' (the scene's camera names) and ATTITUDE_ORDER=0, 1 or 2. "
            "The onboard attitude sigma (ATTITUDE_SIGMA) keeps Plan D's quadratic term from trading off "
            "against the installation angles when the control is sparse. A block of several products (stereo, "
            "tri-stereo, several dates, neighbouring orbits): SCENES instead of SCENE, GCPs, tie points and "
            "image lines (LINES) naming the scene each was measured in (field 'scene'), adjusted together (one "
            "trajectory correction per scene with its own onboard pseudo-observations, an RPC product its own "
            "image-space correction, shared ground points and ground lines; SCENE_SIGMAS gives a scene its own "
            "onboard or vendor sigmas); the outputs go to OUTPUT_FOLDER: "
            "<name>_adjusted.json per scene, block_report.html/.json, adjusted_gcps.gpkg, adjusted_tie_points.gpkg, "
            "line_residuals.gpkg (with LINES) and, with WRITE_RPCS, a refined RPC per image.")
    GCPS, TIE_POINTS, OUTPUT_TIE_POINTS = "GCPS", "TIE_POINTS", "OUTPUT_TIE_POINTS"
    POSITION_MODEL, POSITION_ORDER, POSITION_INTERVAL, POSITION_SIGMA = \
        POSITION_MODEL, "POSITION_ORDER", "POSITION_INTERVAL", "POSITION_SIGMA"
    ATTITUDE_MODEL, ATTITUDE_ORDER, ATTITUDE_INTERVAL, ATTITUDE_SIGMA = \
        ATTITUDE_MODEL, "ATTITUDE_ORDER", "ATTITUDE_INTERVAL", "ATTITUDE_SIGMA"
    INTERIOR, GROUND, ROBUST, ALPHA, ON_SINGULAR, RESIDUAL_SCALE = \
        "INTERIOR", GROUND, ROBUST, "ALPHA", ON_SINGULAR, "RESIDUAL_SCALE"
    VARIANCE_COMPONENTS, MAX_ROBUST_PASSES = "VARIANCE_COMPONENTS", "MAX_ROBUST_PASSES"
    OUTPUT_SCENE, OUTPUT_REPORT, OUTPUT_GCPS, OUTPUT_RESIDUALS = \
        "OUTPUT_SCENE", "OUTPUT_REPORT", "OUTPUT_GCPS", "OUTPUT_RESIDUALS"
    OUTPUT_REPORT_JSON = "OUTPUT_REPORT_JSON"
    RPC_CORRECTION, RPC_SIGMA, OUTPUT_RPC = RPC_CORRECTION, "RPC_SIGMA", "OUTPUT_RPC"
    SCENE_SIGMAS = SCENE_SIGMAS
    CAMERA_TRAJECTORY = CAMERA_TRAJECTORY
    LINES, OUTPUT_LINE_RESIDUALS = "LINES", "OUTPUT_LINE_RESIDUALS"
    SCENE_OR_SCENES = ("adjust one scene (its cameras, or the scenes of one strip)",
                       "adjust several scenes together as a block, each observation naming its scene")
    # The inputs core errors name (core.errors.InputError.parameter) -> this algorithm's parameters.
    CORE_PARAMETERS = {
        "gcps": GCPS, "ties": TIE_POINTS, "lines": LINES, "scene": SCENE,
        "settings.position_model": POSITION_MODEL, "settings.position_order": POSITION_ORDER,
        "settings.position_interval": POSITION_INTERVAL, "settings.position_sigma": POSITION_SIGMA,
        "settings.attitude_model": ATTITUDE_MODEL, "settings.attitude_order": ATTITUDE_ORDER,
        "settings.attitude_interval": ATTITUDE_INTERVAL, "settings.attitude_sigma": ATTITUDE_SIGMA,
        "settings.camera_trajectory": CAMERA_TRAJECTORY, "settings.interior": INTERIOR,
        "settings.interior_selection": INTERIOR_SELECTION, "settings.ground": GROUND, "settings.robust": ROBUST,
        "settings.alpha": ALPHA, "settings.variance_components": VARIANCE_COMPONENTS,
        "settings.max_robust_iterations": MAX_ROBUST_PASSES, "settings.on_singular": ON_SINGULAR,
        "settings.rpc_correction": RPC_CORRECTION, "settings.rpc_sigma": RPC_SIGMA, "scenes": SCENES,
        "settings.scene_sigmas": SCENE_SIGMAS}
    OUTPUT_FOLDER, WRITE_RPCS, ADJUSTED_SCENES = OUTPUT_FOLDER, WRITE_RPCS, ADJUSTED_SCENES

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False, or_scenes=True)
        self.add_parameter(QgsProcessingParameterVectorLayer(self.GCPS, tr("Ground control points (GeoPackage)"),
                                                    [QgsProcessing.TypeVectorPoint], optional=True),
                  tr("The GCP layer written by 'Import ground control points' (GeoPackage): image col/row, "
                     "ground position, role control/check, camera and sigmas of every point. A point seen in "
                     "several cameras is one id in several rows: every camera it is seen in is used. May be left "
                     "out when TIE_POINTS are given and the onboard pseudo-observations hold the datum. With "
                     "SCENES (a block of several scenes) the layer has a field 'scene' naming the scene each row "
                     "was measured in (importgcps with SCENES writes it); one id may be measured in several "
                     "scenes."))
        self.add_parameter(QgsProcessingParameterVectorLayer(self.TIE_POINTS, tr("Tie points"),
                                                             [QgsProcessing.TypeVector], optional=True),
                           tr("Optional. The tie-point layer written by 'Import tie points' (GeoPackage), or any "
                              "layer or table with the fields id, camera, col, row (optional sigma_px, scene): "
                              "image positions of ground points of unknown position seen in two or more cameras "
                              "(Zhang et al. 2015, Zhang et al. 2024). With them the control may be sparse or "
                              "absent (0, 1 or 2 GCPs) when the onboard pseudo-observations (POSITION_SIGMA, "
                              "ATTITUDE_SIGMA) hold what the GCPs leave of the datum; a datum nothing holds is "
                              "named and refused. Points seen in one camera only are left out, named. With SCENES: "
                              "the field scene names each observation's scene (pushbroom:matchtiepoints with SCENES "
                              "writes it), every tie point is seen in two scenes or more, and the tie points join "
                              "all the scenes into one block."))
        for block, what, default_order, default_sigma, unit, sigma_help in (
                ("POSITION", tr("position"), 1, 100.0, "m", tr(
                    "Accuracy of the onboard orbit (GPS), metres per axis: the position corrections at the knots "
                    "enter as pseudo-observations of 0 with this sigma. 0: none (only the GCPs fix the position).")),
                ("ATTITUDE", tr("attitude"), 2, 0.0, "arcsec", tr(
                    "Accuracy of the onboard attitude (star trackers), arcseconds per axis, as pseudo-observations "
                    "of the attitude corrections. 0: none."))):
            self.addParameter(trajectory_model(f"{block}_MODEL", what))
            title = what.capitalize()
            self.add_parameter(QgsProcessingParameterNumber(
                f"{block}_ORDER", tr("{what} polynomial order").format(what=title),
                QgsProcessingParameterNumber.Integer, default_order, minValue=0, maxValue=2),
                tr("0: bias, 1: bias and drift, 2: also a quadratic term (polynomial model only)."))
            self.add_parameter(QgsProcessingParameterNumber(
                f"{block}_INTERVAL", tr("{what} knot interval (s)").format(what=title),
                QgsProcessingParameterNumber.Double, 20.0, minValue=0.01),
                tr("Seconds between orientation images or knots (lagrange and spline models). Shorter intervals "
                   "follow faster motion but let position and attitude trade off (Zheng et al. 2015, Fig. 7-11)."))
            low, high, _ = ONBOARD_SIGMAS[f"{block.lower()}_sigma"]
            low, high = (low / ARCSEC, high / ARCSEC) if unit == "arcsec" else (low, high)
            self.add_parameter(QgsProcessingParameterNumber(
                f"{block}_SIGMA", tr("Onboard {what} sigma ({unit})").format(what=what, unit=unit),
                QgsProcessingParameterNumber.Double, default_sigma, minValue=0.0, maxValue=high),
                sigma_help + " " + tr("Otherwise from {low:g} to {high:g} {unit}.").format(low=low, high=high,
                                                                                         unit=unit))
        self.add_parameter(QgsProcessingParameterString(self.INTERIOR, tr("Interior parameters to estimate"),
                                                        optional=True, defaultValue=""),
                  tr("Interior and installation parameters to estimate, comma-separated; every other one stays "
                  "at the scene's value. 'default' estimates the usual set with priors: every focal-plane camera's "
                  "10 terms with 3 px, the installation angles of every camera but the first with 30 arcsec, the "
                  "shifts and rotation of every CCD chip but the middle one with 2 px (later items override it, e.g. "
                  "'default, NAD.k2=0.5px'). A name alone makes the parameter free; 'name=sigma' makes it weighted "
                  "(a pseudo-observation of 0 correction with that sigma), the sigma in image terms: 'px' is the "
                  "largest displacement the parameter causes at the ends of the detector array, in detector "
                  "pitches (e.g. NAD.k1=2px, HRC.f=1px), 'arcsec' for angles (FWD.roll=30arcsec); a bare number is "
                  "in the parameter's SI unit. Shell "
                  "wildcards match several names: * any text, ? one character. Names use the scene's chip and "
                  "camera names (CBERS-02B: camera HRC, chips HRC-1, HRC-2, HRC-3): {chip}.dx, .dy (CCD shift on "
                  "the focal plane, m) and .theta (CCD rotation, rad), after Zheng et al. 2015; {chip}.ux0, .ux1, "
                  ".uy0, .uy1 (rad) for detectors given by look angles; {camera}.f (focal length correction, m), .dxp, "
                  ".dyp (principal point, m), .k1, .k2 (radial distortion, 1/m2, 1/m4), .p1, .p2 (decentring, 1/m), "
                  ".b1, .b2, .b3 (affinity), after Zhang et al. 2015; {camera}.roll, .pitch, .yaw (installation "
                  "angles, rad; with several cameras free them for all but the reference camera). Example for "
                  "CBERS-02B: 'HRC-1.*, HRC-3.*' (shifts and rotations of the left and right CCDs against the middle "
                  "one); 'HRC-1.*, HRC-3.*, HRC.f=1px' also estimates the focal length, weighted with 1 px at the "
                  "array end. Sets the GCPs cannot separate from the trajectory are reported (see ON_SINGULAR); "
                  "parameters the control cannot support are removed (see INTERIOR_SELECTION). Empty: none "
                  "(trajectory only)."))
        self.add_parameter(interior_selection())
        self.addParameter(camera_trajectory())
        self.addParameter(rpc_correction())
        self.add_parameter(QgsProcessingParameterNumber(self.RPC_SIGMA, tr("RPC scenes: stated accuracy (px)"),
                                                        QgsProcessingParameterNumber.Double, 0.0, optional=True,
                                                        minValue=0.0, maxValue=1e5),
                           tr("The vendor's stated accuracy of RPC images in pixels (e.g. 10 px for Pleiades' ~8 m "
                              "CE90 at 0.7 m), a pseudo-observation of 0 on each term of RPC_CORRECTION, as the "
                              "onboard sigmas are for rigorous scenes. Needed by a block of RPC images tied without "
                              "GCPs: it holds where the block lies (the report names it). 0: none."))
        self.addParameter(scene_sigmas_parameter())
        self.addParameter(ground_mode())
        self.addParameter(robust_method())
        self.add_parameter(QgsProcessingParameterNumber(self.ALPHA, tr("Significance of the outlier test"),
                                               QgsProcessingParameterNumber.Double, 0.001, minValue=1e-9, maxValue=0.2),
                  tr("Probability of flagging a good observation (0.001: |w| > 3.29)."), advanced=True)
        self.add_parameter(QgsProcessingParameterBoolean(self.VARIANCE_COMPONENTS, tr("Estimate variance components"),
                                                         defaultValue=True),
                  tr("Estimate a factor on the stated sigmas per observation group (per camera the image observations "
                     "of control points; apart from them the tie points' observations; ground xy, ground z, "
                     "onboard pseudo-observations) "
                     "from the residuals and use it before the outlier test, so that flags and check figures do not "
                     "depend on how well the sigmas were guessed (Förstner 1979). Off: the stated sigmas are trusted "
                     "as they are."), advanced=True)
        self.add_parameter(QgsProcessingParameterNumber(self.MAX_ROBUST_PASSES, tr("Robust passes at most"),
                                                        QgsProcessingParameterNumber.Integer, 12, minValue=1,
                                                        maxValue=100),
                  tr("Passes of gross error detection and variance component estimation; a run that needs more "
                     "says so (the flags may then be incomplete)."), advanced=True)
        self.add_parameter(on_singular(), advanced=True)
        self.add_parameter(QgsProcessingParameterNumber(self.RESIDUAL_SCALE, tr("Residual vector exaggeration"),
                                               QgsProcessingParameterNumber.Double, 1000.0, minValue=1.0,
                                               maxValue=1e6),
                  tr("Factor by which the ground residual vectors are drawn longer than they are."), advanced=True)
        # the adjusted scene: corrections, parameters with sigmas, settings; optional (SCENES writes OUTPUT_FOLDER)
        self.addParameter(output_scene(optional=True))
        self.add_parameter(QgsProcessingParameterFileDestination(self.OUTPUT_REPORT, tr("Report (HTML)"),
                                                        fileFilter="HTML (*.html)", optional=True),
                  tr("Optional. A report to read: accuracy before/after, decisions, parameters, plots. The same "
                     "figures as JSON go beside it (same name, .json)."))
        gcp_out = QgsProcessingParameterVectorDestination(self.OUTPUT_GCPS, tr("Adjusted GCPs"),
                                                          QgsProcessing.TypeVectorPoint, optional=True)
        gcp_out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(gcp_out, tr("Optional. GeoPackage of the input points with the adjusted residuals "
                  "(res_col, res_row, res_px, res_m), normalised residuals w_col/w_row, redundancy, weight and "
                  "flagged (1 = gross error)."))
        vec_out = QgsProcessingParameterVectorDestination(self.OUTPUT_RESIDUALS, tr("Residual vectors"),
                                                          QgsProcessing.TypeVectorLine, optional=True)
        vec_out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(vec_out, tr("Optional. GeoPackage of lines from each GCP along its ground residual, "
                  "exaggerated RESIDUAL_SCALE times (res_m holds the true length)."))
        self._add_tie_output()
        self.add_parameter(QgsProcessingParameterFileDestination(self.OUTPUT_RPC, tr("Refined RPC (RPC scenes)"),
                                                                 fileFilter="RPC text (*_RPC.TXT)", optional=True),
                           tr("Optional, for a SCENE given by its RPC: the RPC with the adjusted correction in it, "
                              "as <image>_RPC.TXT, which GDAL and QGIS read for <image>.tif beside it. A correction "
                              "of each coordinate by itself (a shift, or an affine one without cross terms a2, b1) is "
                              "folded exactly into the RPC's numerators; one mixing rows and columns (drift, affine) "
                              "is refitted to the adjusted scene (about "
                              "1e-5 px)."))
        self.addOutput(QgsProcessingOutputFile(self.OUTPUT_REPORT_JSON, tr("Report (JSON)")))
        self._add_line_parameters()
        add_block_parameters(self)

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        if block_given(self, parameters, context):
            return run_block(self, parameters, context, feedback)
        scene_path = one_scene_file(self, parameters, context)
        refuse_for_one_scene(self, parameters, context)
        for name in (self.OUTPUT_FOLDER, self.WRITE_RPCS):
            if (user_destination(self, parameters, context, name) if name == self.OUTPUT_FOLDER else
                    self.parameterAsBoolean(parameters, name, context)):
                raise QgsProcessingException(f"{name}: for a block of scenes ({SCENES}) only; the outputs of one "
                                             f"{SCENE} are OUTPUT_SCENE, OUTPUT_REPORT..., its refined RPC OUTPUT_RPC "
                                             "(RPC scenes) or pushbroom:exportrpc")
        outputs = {name: self._destination(parameters, context, name, suffix) for name, suffix in (
            (self.OUTPUT_SCENE, ".json"), (self.OUTPUT_REPORT, ".html"), (self.OUTPUT_GCPS, ".gpkg"),
            (self.OUTPUT_RESIDUALS, ".gpkg"), (self.OUTPUT_TIE_POINTS, ".gpkg"), (self.OUTPUT_RPC, ".txt"),
            (self.OUTPUT_LINE_RESIDUALS, ".gpkg"))}  # '' for the optional ones not asked for
        outputs[self.OUTPUT_SCENE] = outputs[self.OUTPUT_SCENE] or QgsProcessingUtils.generateTempFilename(
            "output_scene.json")  # optional only for a block: one scene's adjusted model is always written
        report_html = outputs[self.OUTPUT_REPORT]
        report_json = str(Path(report_html).with_suffix(".json")) if report_html else ""
        check_outputs(self, parameters, context, {**{name: [path] for name, path in outputs.items()},
                                                  self.OUTPUT_REPORT: [report_html, Output(report_json,
                                                                                           "its JSON report")]})
        scene = load_scene_for(SCENE, scene_path, feedback)
        if outputs[self.OUTPUT_RPC] and not isinstance(scene, RpcScene):
            raise QgsProcessingException(f"{self.OUTPUT_RPC}: only for a SCENE given by its RPC; the RPC of an "
                                         "adjusted rigorous scene is written by 'Export RPC' (pushbroom:exportrpc)")
        ties = self._ties(parameters, context, scene, scene_path, feedback)
        table, gcp_path, gcp_layer = self.gcp_table(parameters, context, ties is not None)
        self._check_tie_outputs(outputs, ties, gcp_path)
        settings = self.adjustment_settings(parameters, context)
        scale = self.parameterAsDouble(parameters, self.RESIDUAL_SCALE, context)
        lines = self._lines(parameters, context)
        # The core's checks (settings, GCPs, tie points, lines, datum) before the (long) solution starts;
        # what the core does not place is about the GCPs.
        with self.core_errors(self.GCPS):
            check_inputs(scene, table, settings, ties, lines)
        self.check_interior(scene, settings.interior)
        if gcp_path:
            feedback.pushInfo(f"{len(table)} points from {gcp_path}: {int((table.role == 'control').sum())} "
                              f"control, {int((table.role == 'check').sum())} check")
        progress, is_cancelled = feedback_callbacks(feedback)
        with self.core_errors():
            result = adjust(scene, table, settings, progress, is_cancelled, ties=ties, lines=lines)
        check_cancelled(feedback)
        feedback.setProgressText("writing the outputs")
        en = core_call(ground_residuals, result.scene, table, result.points["camera"])
        with processing_errors(), atomic_outputs() as files:  # every output or none
            with processing_errors(f"{self.OUTPUT_SCENE}: "):
                save_scene(result.scene, outputs[self.OUTPUT_SCENE], files)
            if outputs[self.OUTPUT_RPC]:
                with processing_errors(f"{self.OUTPUT_RPC}: "):
                    rpc, how = refined_rpc(result.scene)
                    write_rpc(rpc, outputs[self.OUTPUT_RPC], files=files)
                feedback.pushInfo(f"refined RPC ({how}) written to {outputs[self.OUTPUT_RPC]}")
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
            if outputs[self.OUTPUT_LINE_RESIDUALS]:
                self._write_line_residuals(lines, result, outputs[self.OUTPUT_LINE_RESIDUALS], files)
            if outputs[self.OUTPUT_RESIDUALS]:
                with processing_errors(f"{self.OUTPUT_RESIDUALS}: "):
                    write_residual_vectors(result.scene, table, result.points, outputs[self.OUTPUT_RESIDUALS],
                                           scale, en=en, files=files)
            if outputs[self.OUTPUT_TIE_POINTS]:
                with processing_errors(f"{self.OUTPUT_TIE_POINTS}: "):
                    write_adjusted_tie_points(result.tie_points, outputs[self.OUTPUT_TIE_POINTS],
                                              scene_path=outputs[self.OUTPUT_SCENE], files=files)
        style_output_on_load(context, outputs[self.OUTPUT_GCPS], STYLES / "adjusted_gcps.qml")
        style_output_on_load(context, outputs[self.OUTPUT_RESIDUALS], STYLES / "residual_vectors.qml")
        style_output_on_load(context, outputs[self.OUTPUT_TIE_POINTS], STYLES / "adjusted_tie_points.qml")
        style_output_on_load(context, outputs[self.OUTPUT_LINE_RESIDUALS], STYLES / "control_lines.qml")
        self.push_core_lines(feedback, log_lines(result.report, None if ties is None else len(ties)))
        feedback.setProgress(100)
        return {**{name: path or None for name, path in outputs.items()}, self.OUTPUT_REPORT_JSON: report_json or None}

    # --- control lines ---------------------------------------------------------------------
    def _add_line_parameters(self) -> None:
        self.add_parameter(QgsProcessingParameterVectorLayer(self.LINES, tr("Control lines (GeoPackage)"),
                                                             [QgsProcessing.TypeVectorLine], optional=True),
                           tr("The control lines written by 'Import control lines' (pushbroom:importlines): "
                              "ground lines and the image lines paired to them (Tommaselli & Marcato Junior 2012). "
                              "Each image-line point constrains its ground point to its line across it and in "
                              "height; lines that do not fit as a whole are named and released. With SCENES (a block "
                              "of several scenes) the layer image_lines has a text field 'scene' naming the scene "
                              "each image line was measured in (as SCENES names it: its file's stem; the line "
                              "digitising dock writes it when its Scene field is set); the ground lines are shared "
                              "by all scenes. Control lines need rigorous scene models: not with RPC products."))
        out = QgsProcessingParameterVectorDestination(self.OUTPUT_LINE_RESIDUALS, tr("Line residuals"),
                                                      QgsProcessing.TypeVectorPoint, optional=True,
                                                      createByDefault=False)
        out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(out, tr("GeoPackage with layer line_points (each image-line point at its adjusted "
                                   "ground, its image residual and across-line offset in m) and ground_lines (per "
                                   "line RMS and max across-line offset, flagged = 1 for lines named wrong)."))

    def _lines(self, parameters, context):
        """ControlLines of the LINES GeoPackage (None without)."""
        layer = self.parameterAsVectorLayer(parameters, self.LINES, context)
        if layer is None:
            return None
        path, _ = ogr_source(self.LINES, layer, "control lines")
        with processing_errors(f"{self.LINES}: "):
            return ControlLines(read_ground_lines(path), read_image_lines(path))

    def _write_line_residuals(self, lines, result, path: str, files) -> None:
        if lines is None:
            raise QgsProcessingException(f"{self.OUTPUT_LINE_RESIDUALS}: no LINES given")
        with processing_errors(f"{self.OUTPUT_LINE_RESIDUALS}: "):
            write_line_residuals(path, lines, result.lines, result.report["lines"], files)

    # --- parameters -------------------------------------------------------------------------
    def gcp_table(self, parameters, context, with_ties: bool = False) -> tuple[gcps.GcpTable, str, str | None]:
        """The GCP table, the GeoPackage's path and its layer name (None: the first layer); with
        tie points and no GCP layer, an empty table and path ''."""
        layer = self.parameterAsVectorLayer(parameters, self.GCPS, context)
        if layer is None and with_ties:
            none = np.zeros(0)
            return gcps.GcpTable(*(np.zeros(0, str),) * 3, *(none,) * 8), "", None
        if layer is None:
            raise QgsProcessingException(f"{self.GCPS}: no GCP layer given (it may be left out only with "
                                         f"{self.TIE_POINTS})")
        path, name = split_ogr_source(layer.source())
        source = layer.source()
        if layer.providerType() != "ogr" or not path.lower().endswith(".gpkg"):
            raise QgsProcessingException(f"{self.GCPS}: {source} is not a GeoPackage; write the GCPs with 'Import "
                                         "ground control points' (pushbroom:importgcps) first")
        with processing_errors(f"{self.GCPS}: "):
            return gcps.read_gpkg(path, name), path, name

    # --- tie points ---------------------------------------------------------------------------
    def _add_tie_output(self) -> None:
        out = QgsProcessingParameterVectorDestination(self.OUTPUT_TIE_POINTS, tr("Adjusted tie points"),
                                                      QgsProcessing.TypeVectorPoint, optional=True)
        out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(out, tr("Optional, with TIE_POINTS. GeoPackage point layer (EPSG:4979), one feature per "
                                   "tie observation at its point's adjusted ground position (empty geometry for "
                                   "points left out): id, camera, col, row, res_col, res_row, res_px (px, predicted "
                                   "- measured), w_col, w_row (normalised residuals), weight (final robust weight "
                                   "factor), flagged (1 = gross error, drawn red)."))

    def _ties(self, parameters, context, scene, scene_path: str, feedback) -> tiepoints.TieTable | None:
        """The observations of TIE_POINTS (None when not given): a file layer read by
        core.tiepoints.read_gpkg, any other layer from its features. A layer whose scene
        metadata names another scene file gets a warning."""
        if parameters.get(self.TIE_POINTS) in (None, ""):
            return None
        layer = self.parameterAsVectorLayer(parameters, self.TIE_POINTS, context)
        if layer is None:
            raise QgsProcessingException(f"{self.TIE_POINTS}: {parameters[self.TIE_POINTS]} is not a vector layer "
                                         "or table; give the layer written by 'Import tie points'")
        if isinstance(scene, RpcScene):
            raise QgsProcessingException(f"{self.TIE_POINTS}: tie points need a rigorous (physical) scene model with "
                                         "several cameras; this SCENE is given by its RPC (one image)")
        with processing_errors(f"{self.TIE_POINTS}: "):
            table = read_tie_layer(layer)
        made_for = table.scene_path
        if made_for and Path(made_for).resolve() != Path(scene_path).resolve():
            feedback.pushWarning(f"{self.TIE_POINTS}: the layer was checked against the scene {made_for}, not "
                                 f"SCENE {scene_path}; its cameras and image positions must be this scene's")
        feedback.pushInfo(f"{len(table)} tie observations from {layer.source()}")
        # the checks of 'Import tie points' against this scene (cameras, duplicates, image, spread)
        with core_log_to(feedback, tiepoints.__name__), processing_errors(f"{self.TIE_POINTS}: "):
            return tiepoints.check_against_scene(table, scene, scene_path, source=layer.source())

    def _check_tie_outputs(self, outputs: dict, ties, gcp_path: str) -> None:
        """Outputs that need an input that was not given."""
        if outputs[self.OUTPUT_TIE_POINTS] and ties is None:
            raise QgsProcessingException(f"{self.OUTPUT_TIE_POINTS}: the adjusted tie points need {self.TIE_POINTS}")
        for name in (self.OUTPUT_GCPS, self.OUTPUT_RESIDUALS):
            if outputs[name] and not gcp_path:
                raise QgsProcessingException(f"{name}: there are no GCPs to write (no {self.GCPS} given)")

    def check_interior(self, scene, interior: str) -> None:
        """INTERIOR's names and sigmas against a rigorous scene's parameters; the error lists the
        scene's cameras and CCD chips, whose names the patterns use. (The core refuses INTERIOR for
        an RPC scene.)"""
        if isinstance(scene, RpcScene):
            return
        t_min, t_max = scene.time_span()
        basis = TimeBasis.covering("polynomial", t_min, t_max, 0)
        try:
            ParameterSet(scene, basis, basis, interior)
        except PushbroomError as exc:
            names = "; ".join(f"camera {c.name} with chips " + ", ".join(ch.name or f"{c.name}-{k + 1}"
                                                                       for k, ch in enumerate(c.chips))
                              for c in scene.cameras)
            raise QgsProcessingException(f"{self.INTERIOR}: {exc}. This scene has {names}.") from None

    def adjustment_settings(self, parameters, context) -> AdjustmentSettings:
        number = lambda name: self.parameterAsDouble(parameters, name, context)  # noqa: E731
        position_sigma, attitude_sigma = number(self.POSITION_SIGMA), number(self.ATTITUDE_SIGMA)
        return AdjustmentSettings(
            position_model=enum_value(self, parameters, self.POSITION_MODEL, context),
            position_order=self.parameterAsInt(parameters, self.POSITION_ORDER, context),
            position_interval=number(self.POSITION_INTERVAL),
            attitude_model=enum_value(self, parameters, self.ATTITUDE_MODEL, context),
            attitude_order=self.parameterAsInt(parameters, self.ATTITUDE_ORDER, context),
            attitude_interval=number(self.ATTITUDE_INTERVAL),
            position_sigma=position_sigma or None, attitude_sigma=attitude_sigma * ARCSEC or None,
            camera_trajectory=enum_value(self, parameters, self.CAMERA_TRAJECTORY, context),
            interior=self.parameterAsString(parameters, self.INTERIOR, context),
            interior_selection=enum_value(self, parameters, INTERIOR_SELECTION, context),
            ground=enum_value(self, parameters, self.GROUND, context),
            robust=enum_value(self, parameters, self.ROBUST, context),
            alpha=number(self.ALPHA),
            variance_components=self.parameterAsBoolean(parameters, self.VARIANCE_COMPONENTS, context),
            max_robust_iterations=self.parameterAsInt(parameters, self.MAX_ROBUST_PASSES, context),
            on_singular=enum_value(self, parameters, self.ON_SINGULAR, context),
            rpc_correction=enum_value(self, parameters, self.RPC_CORRECTION, context),
            rpc_sigma=number(self.RPC_SIGMA) or None)

    def _destination(self, parameters, context, name: str, suffix: str) -> str:
        path = self.output_path(parameters, context, name, name.lower() + suffix)
        if path and Path(path).suffix.lower() != suffix:
            raise QgsProcessingException(f"{name}: expected a {suffix} file (got {path})")
        return path
