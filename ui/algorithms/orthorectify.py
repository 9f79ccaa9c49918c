"""pushbroom:orthorectify — the raw image resampled onto a map grid with the rigorous scene
model and a DEM: a tiled, compressed GeoTIFF with overviews; or every camera (and every scene
of a strip) in one run, into a folder."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError
from qgis.core import (QgsCoordinateReferenceSystem, QgsGeometry, QgsPointXY,
                       QgsProcessingException, QgsProcessingOutputMultipleLayers, QgsProcessingParameterBoolean,
                       QgsProcessingParameterCrs, QgsProcessingParameterExtent,
                       QgsProcessingParameterFolderDestination,
                       QgsProcessingParameterNumber, QgsProcessingParameterRasterDestination,
                       QgsProcessingParameterString, QgsProcessingUtils, QgsRectangle)

from ...core.dem import ConstantHeight
from ...core.products.ortho import (check_images, default_grid, gap_sentence, orthorectify, orthorectify_products,
                                    scene_utm_crs, strip_products)
from ...core.products.footprint import footprints
from ..feedback import core_call, feedback_callbacks, processing_errors
from ..inputs import (add_dem_parameters, add_scene_parameters, camera_for, camera_images_for, dem_from_parameters,
                      load_scene_for, raster_file)
from ..outputs import check_outputs
from ..parameters import CAMERA, DEM, INPUTS, RESAMPLING, SCENE, RasterInput, camera_images, enum_value, resampling, tr
from .base import PushbroomAlgorithm


class OrthorectifyAlgorithm(PushbroomAlgorithm):
    ID = "orthorectify"
    NAME = "Orthorectify"
    GROUP, GROUP_ID = "Products", "products"
    HELP = ("Resamples a raw pushbroom image onto a north-up map grid with the scene's rigorous model (onboard "
            "or adjusted) and a DEM. Every output pixel's image position is computed exactly on a coarse grid "
            "and densified within 0.01 px of the exact model, on any DEM: checked at every cell of the grid, "
            "the relief of a DSM's steps between the nodes corrected pixel by pixel, cells along the seams of "
            "staggered CCD arrays and cells failing the check mapped exactly; the log states the figure met. "
            "Works in tiles on all cores with bounded memory "
            "(raw images over 1 GiB are read window by window); "
            "writes a tiled, DEFLATE-compressed GeoTIFF with overviews and nodata, completely or not at all. "
            "With a DEM that covers only part of the scene, or with nodata holes, give an EXTENT inside it: "
            "pixels without a height are nodata and a warning counts the output pixels of the image's footprint "
            "with no height (off the DEM, on its holes). "
            "With ALL_CAMERAS, every camera of the scene (e.g. the forward, nadir and backward lines of a "
            "three-line camera) is orthorectified in one run from INPUTS (one raw image per camera, in the scene's "
            "camera order) into ORTHO_FOLDER as ortho_<CAMERA>.tif; a strip of several scenes in one image per "
            "camera (as the simulator writes, info.n_scenes) gives one orthoimage per camera and scene, "
            "ortho_<CAMERA>_s<k>.tif (k = 1, 2, ... along the pass), each on its own grid. All of them are "
            "written, or none. SCHEDULER (advanced) sends the tiles to a Dask distributed cluster instead of this "
            "machine's threads: the same bytes.")
    INPUT, CRS_PARAM, RESOLUTION, RESAMPLING_PARAM, NODATA, EXTENT, OUTPUT = \
        "INPUT", "CRS", "RESOLUTION", RESAMPLING, "NODATA", "EXTENT", "OUTPUT"
    ALL_CAMERAS, INPUTS, ORTHO_FOLDER, ORTHOIMAGES, SCHEDULER = \
        "ALL_CAMERAS", INPUTS, "ORTHO_FOLDER", "ORTHOIMAGES", "SCHEDULER"
    CORE_PARAMETERS = {"resolution": RESOLUTION}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.add_parameter(RasterInput(self.INPUT, tr("Raw image"), optional=True),
                  tr("The scene's raw image (any GDAL format, any number of bands and data type), of the size the "
                  "scene's camera images, without georeferencing. Required unless ALL_CAMERAS."))
        self.add_parameter(QgsProcessingParameterBoolean(self.ALL_CAMERAS, tr("Every camera of the scene"), False,
                                                         optional=True),
                  tr("Orthorectify every camera of the scene (and every scene of a strip) in one run, from INPUTS "
                     "into ORTHO_FOLDER; CAMERA, INPUT and OUTPUT are then not used."))
        self.addParameter(camera_images())
        add_scene_parameters(self)
        add_dem_parameters(self)
        self.add_parameter(QgsProcessingParameterCrs(self.CRS_PARAM, tr("Output CRS"), optional=True),
                  tr("Projected CRS of the orthoimage. Empty: the WGS84 UTM zone of the scene's centre."))
        self.add_parameter(QgsProcessingParameterNumber(self.RESOLUTION, tr("Pixel size (m)"),
                                                        QgsProcessingParameterNumber.Double, optional=True,
                                                        minValue=0.0),
                  tr("Output pixel size in the CRS's units (metres). Empty or 0: the ground sample distance at the "
                     "image centre."))
        self.addParameter(resampling())
        self.add_parameter(QgsProcessingParameterNumber(self.NODATA, tr("Nodata value"),
                                                        QgsProcessingParameterNumber.Double, 0.0),
                           tr("Value of output pixels the image does not cover (and nodata in the GeoTIFF)."))
        self.add_parameter(QgsProcessingParameterExtent(self.EXTENT, tr("Extent"), optional=True),
                  tr("Part of the scene to produce (any CRS). Empty: the whole footprint of the image on the DEM."),
                  advanced=True)
        self.add_parameter(QgsProcessingParameterRasterDestination(self.OUTPUT, tr("Orthoimage"), optional=True),
                  tr("GeoTIFF (tiled 512 x 512, DEFLATE, overviews, nodata set). Not used with ALL_CAMERAS."))
        self.add_parameter(QgsProcessingParameterFolderDestination(self.ORTHO_FOLDER, tr("Folder of the orthoimages"),
                                                                   optional=True),
                  tr("With ALL_CAMERAS: the folder (created when its parent exists) the orthoimages are written "
                     "to, ortho_<CAMERA>.tif or, for a strip, ortho_<CAMERA>_s<k>.tif; files of those names there "
                     "are replaced."))
        self.add_parameter(QgsProcessingParameterString(self.SCHEDULER, tr("Dask scheduler address"), optional=True),
                  tr("Empty (default): the tiles run on this machine's cores (threads). An address such as "
                     "tcp://host:8786: the tiles run as jobs on that Dask distributed cluster, whose workers must "
                     "import this plugin and reach the input and output files at the same paths; each writes its "
                     "tile beside the output and the tiles are assembled here into the same bytes."), advanced=True)
        self.addOutput(QgsProcessingOutputMultipleLayers(self.ORTHOIMAGES, tr("Orthoimages (ALL_CAMERAS)")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        if self.parameterAsBool(parameters, self.ALL_CAMERAS, context):
            return self._all_cameras(parameters, context, feedback)
        output = (self.output_path(parameters, context, self.OUTPUT, "orthoimage.tif")
                  or QgsProcessingUtils.generateTempFilename("orthoimage.tif"))
        if Path(output).suffix.lower() not in (".tif", ".tiff"):
            raise QgsProcessingException(f"{self.OUTPUT}: the orthoimage is written as GeoTIFF; use a .tif file "
                                         f"(got {output})")
        check_outputs(self, parameters, context, {self.OUTPUT: [output]})
        image = raster_file(self, parameters, self.INPUT, context)
        if not image:
            raise QgsProcessingException(f"{self.INPUT}: no raw image given (or set {self.ALL_CAMERAS} with "
                                         f"{self.INPUTS} for every camera)")
        scene = load_scene_for(SCENE, self.parameterAsFile(parameters, SCENE, context), feedback)
        camera = camera_for(CAMERA, scene, self.parameterAsString(parameters, CAMERA, context))
        with processing_errors(f"{self.INPUT}: "):
            check_images(scene, {camera: image})
        surface = dem_from_parameters(self, parameters, context, scene, feedback)
        crs = self._crs(parameters, context)
        extent = None
        if parameters.get(self.EXTENT):
            crs = crs or core_call(scene_utm_crs, scene, camera, surface)  # the extent needs its CRS first
            rect = self.parameterAsExtent(parameters, self.EXTENT, context,
                                          QgsCoordinateReferenceSystem(crs.to_wkt()))
            extent = (rect.xMinimum(), rect.yMinimum(), rect.xMaximum(), rect.yMaximum())
            self._check_extent(scene, camera, surface, crs, extent, feedback)
        resolution = self.parameterAsDouble(parameters, self.RESOLUTION, context) or None
        feedback.setProgressText("planning the output grid")
        with self.core_errors():
            grid = default_grid(scene, camera, surface, crs, resolution, extent)
        feedback.pushInfo(f"orthoimage {grid.cols} x {grid.rows} px at {grid.resolution:.3f} m in "
                          f"{grid.crs.to_string()}")
        progress, is_cancelled = feedback_callbacks(feedback)
        figures = core_call(orthorectify, scene, image, surface, output, camera, grid,
                            is_cancelled=is_cancelled, progress=progress, **self._options(parameters, context))
        self._report(feedback, figures, surface)
        return {self.OUTPUT: output}

    def _options(self, parameters, context) -> dict:
        """Resampling, nodata and scheduler for core.ortho.orthorectify."""
        return {"resampling": enum_value(self, parameters, self.RESAMPLING_PARAM, context),
                "nodata": self.parameterAsDouble(parameters, self.NODATA, context),
                "scheduler": self.parameterAsString(parameters, self.SCHEDULER, context).strip() or None}

    def _report(self, feedback, figures: dict, surface, name: str = "") -> None:
        feedback.pushInfo(f"{name}written in {figures['seconds']:.1f} s; {figures['mapping']}")
        if figures["dem_gap_pixels"]:
            feedback.pushWarning(f"{DEM}: {name}{gap_sentence(surface, figures)}")

    def _all_cameras(self, parameters, context, feedback) -> dict:
        """Every camera (and scene of a strip) of SCENE from INPUTS into ORTHO_FOLDER."""
        folder = self.parameterAsString(parameters, self.ORTHO_FOLDER, context)
        if not folder or folder == "TEMPORARY_OUTPUT":
            folder = QgsProcessingUtils.tempFolder()
        if Path(folder).is_file():
            raise QgsProcessingException(f"{self.ORTHO_FOLDER}: {folder} is a file, not a folder; give a folder for "
                                         "the orthoimages (created when its parent exists)")
        scene = load_scene_for(SCENE, self.parameterAsFile(parameters, SCENE, context), feedback)
        images = camera_images_for(self, parameters, context, scene)
        products = strip_products(scene, list(images))
        made = not Path(folder).exists() and Path(folder).parent.is_dir()
        if made:
            Path(folder).mkdir()
        try:
            return self._write_products(parameters, context, feedback, scene, images, products, Path(folder))
        except BaseException:
            if made and not any(Path(folder).iterdir()):
                Path(folder).rmdir()
            raise

    def _write_products(self, parameters, context, feedback, scene, images, products, folder: Path) -> dict:
        outputs = [folder / p.name for p in products]
        check_outputs(self, parameters, context, {self.ORTHO_FOLDER: outputs})
        with processing_errors(f"{self.INPUTS}: "):
            check_images(scene, images)
        for k, image in images.items():
            feedback.pushInfo(f"camera {scene.cameras[k].name}: {image}")
        surface = dem_from_parameters(self, parameters, context)
        crs = self._crs(parameters, context)
        resolution = self.parameterAsDouble(parameters, self.RESOLUTION, context) or None
        grids = []
        feedback.setProgressText("planning the output grids")
        for product in products:
            extent = None
            if parameters.get(self.EXTENT):
                crs = crs or core_call(scene_utm_crs, scene, product.camera, surface)
                rect = self.parameterAsExtent(parameters, self.EXTENT, context,
                                              QgsCoordinateReferenceSystem(crs.to_wkt()))
                extent = (rect.xMinimum(), rect.yMinimum(), rect.xMaximum(), rect.yMaximum())
                self._check_extent(scene, product.camera, surface, crs, extent, feedback)
            with self.core_errors():
                grids.append(default_grid(scene, product.camera, surface, crs, resolution, extent, product.rows))
            g = grids[-1]
            feedback.pushInfo(f"{product.name}: {g.cols} x {g.rows} px at {g.resolution:.3f} m in "
                              f"{g.crs.to_string()}")
        progress, is_cancelled = feedback_callbacks(feedback)
        figures = core_call(orthorectify_products, scene, images, surface, folder, products, grids,
                            progress=progress, is_cancelled=is_cancelled, **self._options(parameters, context))
        for product, fig in zip(products, figures):
            self._report(feedback, fig, surface, f"{product.name}: ")
        return {self.ORTHO_FOLDER: str(folder), self.ORTHOIMAGES: [str(p) for p in outputs]}

    def _check_extent(self, scene, camera: int, surface, crs: CRS, extent: tuple, feedback) -> None:
        """Refuse an EXTENT that misses the image's footprint (traced at the terrain's mean
        height), warn with the share of it outside."""
        box = QgsGeometry.fromRect(QgsRectangle(*extent))
        if not box.area() > 0:
            raise QgsProcessingException(f"{self.EXTENT}: the extent {extent} is empty")
        flat = ConstantHeight(float(np.mean(surface.height_range)))
        (outline,) = core_call(footprints, scene, flat, cameras=[camera], samples_per_edge=32)
        x, y = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True).transform(outline.lon, outline.lat)
        footprint = QgsGeometry.fromPolygonXY([[QgsPointXY(float(a), float(b)) for a, b in zip(x, y)]])
        share = footprint.intersection(box).area() / box.area()
        if share <= 0:
            raise QgsProcessingException(f"{self.EXTENT}: the extent does not overlap the image's footprint "
                                         f"({footprint.boundingBox().toString(0)} in {crs.to_string()})")
        if share < 0.999:
            feedback.pushWarning(f"{self.EXTENT}: {100 * (1 - share):.1f} % of the extent lies outside the image's "
                                 f"footprint; those pixels are nodata")

    def _crs(self, parameters, context) -> CRS | None:
        """The output CRS as pyproj's, or None for the default (UTM); geographic CRSs refused."""
        qcrs = self.parameterAsCrs(parameters, self.CRS_PARAM, context)
        if not qcrs.isValid():
            if parameters.get(self.CRS_PARAM):
                raise QgsProcessingException(f"{self.CRS_PARAM}: unknown CRS {parameters.get(self.CRS_PARAM)!r}")
            return None
        try:
            crs = CRS.from_wkt(qcrs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED))
        except CRSError as exc:
            raise QgsProcessingException(f"{self.CRS_PARAM}: unknown CRS {qcrs.authid()} ({exc})") from None
        if not crs.is_projected:
            raise QgsProcessingException(f"{self.CRS_PARAM}: {qcrs.authid() or crs.name} is not a projected CRS; "
                                         "choose one in metres (e.g. the scene's UTM zone)")
        return crs
