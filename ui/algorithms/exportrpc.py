"""pushbroom:exportrpc — RPC00B rational polynomials fitted to the rigorous model, written where
GDAL and QGIS read them, with the fit's check figures per CCD."""
from pathlib import Path

from qgis.core import (QgsProcessingException, QgsProcessingOutputFile, QgsProcessingOutputNumber,
                       QgsProcessingOutputRasterLayer, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterNumber)

from ...core.dem import ConstantHeight
from ...core.files import Output, atomic_outputs
from ...core.formats.rpcfiles import image_vrt_with_rpc, report_path, write_rpc
from ...core.products import rpcfit
from ...core.products.rpcfit import dem_height_range, fit_rpc
from ..feedback import check_cancelled, core_call, core_log_to, feedback_callbacks, processing_errors
from ..inputs import (add_dem_parameters, add_scene_parameters, camera_for, dem_from_parameters, load_scene_for,
                      raster_file)
from ..outputs import check_outputs
from ..parameters import CAMERA, DEM, SCENE, RasterInput, tr
from .base import PushbroomAlgorithm


class ExportRpcAlgorithm(PushbroomAlgorithm):
    ID = "exportrpc"
    NAME = "Export RPC"
    GROUP, GROUP_ID = "Products", "products"
    HELP = ("Fits an RPC00B model (third-order rational polynomials, the form GDAL, QGIS and most "
            "photogrammetric software read) to one camera of the scene's rigorous sensor model, over the whole "
            "image and the terrain's height range, and checks it on an independent grid (other image positions, "
            "other heights, both ends of the height range). The fit error is logged and written as JSON, overall, "
            "per CCD chip and at the height-range ends. On single-chip cameras it is a few hundred-thousandths "
            "of a pixel. A camera of several separately aligned (staggered) CCDs steps at the chip seams, which "
            "one smooth RPC cannot follow: the per-CCD and seam figures show how large that is. "
            "GDAL finds the RPC of an image <name>.<ext> in the file <name>_RPC.TXT or <name>.RPB in the same "
            "folder (so name OUTPUT after the image, in the image's folder, if you want that), or in a GeoTIFF's "
            "RPC tag or a VRT's RPC metadata. With IMAGE, a small VRT beside OUTPUT shows the image with the RPC; "
            "the image itself is never modified. In QGIS, use it with Raster > Projections > Warp (Reproject) "
            "with the transformer option RPC (optionally RPC_DEM=<dem>), or gdalwarp -rpc; RPC heights are "
            "ellipsoidal, so a sea-level DEM must declare its vertical CRS (e.g. EPSG:4326+5773) for GDAL to "
            "convert it. "
            "Image coordinates follow GDAL: (0, 0) is the upper-left corner of the first pixel; in the RPC "
            "file, sample = col - 0.5 and line = row - 0.5 as GDAL's RPC transformer expects.")
    HEIGHT_SPAN, GRID, HEIGHT_LEVELS, REGULARISATION = "HEIGHT_SPAN", "GRID", "HEIGHT_LEVELS", "REGULARISATION"
    IMAGE, OUTPUT = "IMAGE", "OUTPUT"
    REPORT, IMAGE_WITH_RPC, RMS_PX, MAX_PX = "REPORT", "IMAGE_WITH_RPC", "RMS_PX", "MAX_PX"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self)
        add_dem_parameters(self)
        self.add_parameter(
            QgsProcessingParameterNumber(self.HEIGHT_SPAN, tr("Height span without a DEM (± m)"),
                                         QgsProcessingParameterNumber.Double, 500.0, minValue=1.0,
                                         maxValue=10000.0),
            tr("Without a DEM the RPC is fitted from HEIGHT - HEIGHT_SPAN to HEIGHT + HEIGHT_SPAN (metres, "
               "ellipsoidal); outside that range it extrapolates. With a DEM, the range is the DEM's heights over "
               "the image plus a margin (10 % of their span, at least 50 m)."))
        self.add_parameter(
            QgsProcessingParameterNumber(self.GRID, tr("Fit grid nodes across and along the image"),
                                         QgsProcessingParameterNumber.Integer, 31, minValue=4, maxValue=201),
            tr("The rigorous model is sampled on this many image columns and rows (image edges included) at "
               "each height level; 31 is plenty for a cubic RPC."), advanced=True)
        self.add_parameter(
            QgsProcessingParameterNumber(self.HEIGHT_LEVELS, tr("Fit height levels"),
                                         QgsProcessingParameterNumber.Integer, 7, minValue=4, maxValue=51),
            tr("Number of heights, from the bottom to the top of the height range, at which the grid is "
               "sampled (a cubic in height needs at least 4)."), advanced=True)
        self.add_parameter(
            QgsProcessingParameterNumber(self.REGULARISATION, tr("Regularisation (Tikhonov)"),
                                         QgsProcessingParameterNumber.Double, 1e-12, minValue=0.0, maxValue=1e-2),
            tr("Ridge weight, relative to the normalised normal equations, that keeps the denominators tame. "
               "It is raised 100-fold at a time (up to 1e-4; the value used is reported) while the denominator "
               "vanishes at a fit node or the independent check's largest error exceeds twice the fit's."),
            advanced=True)
        self.add_parameter(
            RasterInput(self.IMAGE, tr("Image of this camera (optional)"), optional=True),
            tr("The raw image the scene's camera took (same size as the camera's image). When given, a VRT "
               "named after OUTPUT (e.g. scene_RPC.TXT -> scene.vrt) is written beside OUTPUT: it shows the "
               "image unchanged, with the RPC in its metadata, so GDAL and QGIS can orthorectify it. The image "
               "file itself is never modified."))
        self.add_parameter(
            QgsProcessingParameterFileDestination(self.OUTPUT, tr("RPC file"), "RPC text (*_RPC.TXT);;RPB (*.RPB)",
                                                  defaultValue=None),
            tr("Where to write the RPC: a name ending in _RPC.TXT writes GDAL's RPC text (the DigitalGlobe "
               "'KEY: value' layout), .RPB the RPB layout. GDAL uses it for an image called <name>.<ext> in the "
               "same folder. The fit report is written beside it as <OUTPUT>.json."))
        self.addOutput(QgsProcessingOutputFile(self.REPORT, tr("Fit report (JSON): errors overall, per CCD, "
                                                               "at the height-range ends")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.IMAGE_WITH_RPC, tr("Image with RPC (VRT), when "
                                                                              "IMAGE is given")))
        self.addOutput(QgsProcessingOutputNumber(self.RMS_PX, tr("Check RMS error (px)")))
        self.addOutput(QgsProcessingOutputNumber(self.MAX_PX, tr("Check maximum error (px)")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        out = Path(self.output_path(parameters, context, self.OUTPUT, "image_RPC.TXT"))
        name = out.name.lower()
        if not (name.endswith(".txt") or name.endswith(".rpb")):
            raise QgsProcessingException(f"{self.OUTPUT}: {out} must end in _RPC.TXT (GDAL's RPC text) or .RPB")
        if name.endswith(".txt") and not name.endswith("_rpc.txt"):
            feedback.pushWarning(f"{out.name} does not end in _RPC.TXT: GDAL will not find it beside an image "
                                 f"by itself")
        image = raster_file(self, parameters, self.IMAGE, context)
        stem = out.name[:-len("_RPC.TXT")] if name.endswith("_rpc.txt") else out.stem
        vrt = out.with_name(stem + ".vrt") if image else None
        check_outputs(self, parameters, context, {self.OUTPUT: [out, Output(report_path(out), "its fit report"),
                                                                 Output(vrt, "the VRT of IMAGE with the RPC")]})
        scene = load_scene_for(SCENE, self.parameterAsFile(parameters, SCENE, context), feedback)
        camera = camera_for(CAMERA, scene, self.parameterAsString(parameters, CAMERA, context))
        cam = scene.cameras[camera]
        surface = dem_from_parameters(self, parameters, context, scene, feedback)
        if isinstance(surface, ConstantHeight):
            span = self.parameterAsDouble(parameters, self.HEIGHT_SPAN, context)
            heights = (surface.value - span, surface.value + span)
        else:
            feedback.setProgressText("height range of the DEM over the image")
            with processing_errors(f"{DEM}: "), core_log_to(feedback, rpcfit.__name__):
                heights = dem_height_range(scene, surface, camera)
        check_cancelled(feedback)
        grid = self.parameterAsInt(parameters, self.GRID, context)
        levels = self.parameterAsInt(parameters, self.HEIGHT_LEVELS, context)
        progress, _ = feedback_callbacks(feedback)
        rpc, report = core_call(fit_rpc, scene, camera, heights, grid=(grid, grid, levels),
                                regularisation=self.parameterAsDouble(parameters, self.REGULARISATION, context),
                                progress=lambda f, m=None: progress(0.9 * f, m))
        check_cancelled(feedback)
        report["scene"] = str(self.parameterAsFile(parameters, SCENE, context))
        self._log(feedback, report)

        with processing_errors(f"{self.OUTPUT}: "), atomic_outputs() as files:  # all three files or none
            if vrt is not None:
                with processing_errors(f"{self.IMAGE}: "):
                    image_vrt_with_rpc(rpc, image, vrt, cam.cols, cam.rows, files)
                report["image"] = image
                report["image_with_rpc"] = str(vrt)
            write_rpc(rpc, out, report, files)
        feedback.pushInfo(f"RPC written to {out} (report {report_path(out)})" +
                          (f"; image with RPC: {vrt}" if vrt else ""))
        feedback.setProgress(100.0)
        check = report["check"]
        return {self.OUTPUT: str(out), self.REPORT: str(report_path(out)),
                self.IMAGE_WITH_RPC: str(vrt) if vrt else None,
                self.RMS_PX: check["rms_px"], self.MAX_PX: check["max_px"]}

    @staticmethod
    def _log(feedback, report) -> None:
        check = report["check"]
        lo, hi = report["height_range"]
        feedback.pushInfo(f"camera {report['camera']}: RPC00B fitted on {report['fit']['points']} points, heights "
                          f"{lo:.0f} to {hi:.0f} m (ellipsoidal); regularisation used "
                          f"{report['regularisation_used']:g}")
        feedback.pushInfo(f"check on {check['points']} independent points: RMS {check['rms_px']:.4f} px, "
                          f"max {check['max_px']:.4f} px")
        for end, fig in check["heights"].items():
            feedback.pushInfo(f"  at the {end} end ({fig['height_m']:.0f} m): RMS {fig['rms_px']:.4f} px, "
                              f"max {fig['max_px']:.4f} px")
        for chip in check["chips"]:
            if chip["rms_px"] is not None:
                feedback.pushInfo(f"  CCD {chip['name']} (cols {chip['cols'][0]:.0f}-{chip['cols'][1]:.0f}): "
                                  f"RMS {chip['rms_px']:.4f} px, max {chip['max_px']:.4f} px")
        for step in check.get("seam_steps", []):
            feedback.pushInfo(f"  seam at col {step['col']:.0f}: the rigorous model steps by {step['mean_px']:.3f} px")
        if "note" in check:
            feedback.pushWarning(check["note"])
        hint = sensor_corrected_hint(report)
        if hint:
            feedback.pushWarning(hint)


SUB_PIXEL = 0.1  # px: an RPC worse than this at the chip seams is not the sub-pixel model users expect


def sensor_corrected_hint(report: dict) -> str | None:
    """For a camera of several chips whose RPC misses the rigorous model at the seams by more
    than SUB_PIXEL (max), the way to a sub-pixel RPC: the sensor-corrected product."""
    seams = report["check"].get("seams")
    if len(report["check"]["chips"]) < 2 or not seams or seams["max_px"] <= SUB_PIXEL:
        return None
    return (f"camera {report['camera']}: this RPC misses the rigorous model by up to {seams['max_px']:.2f} px at the "
            f"CCD seams (RMS {seams['rms_px']:.2f} px), which no RPC of the raw image can avoid. For an image with "
            "a sub-pixel RPC, make the sensor-corrected product with pushbroom:sensorcorrect: the chips resampled "
            "through the adjusted model onto one straight virtual detector line, which one RPC describes to "
            "hundredths of a pixel; export the RPC of that product (its own SCENE) instead")
