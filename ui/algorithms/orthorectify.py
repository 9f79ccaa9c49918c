"""pushbroom:orthorectify — the raw image resampled onto a map grid with the rigorous scene
model and a DEM: a tiled, compressed GeoTIFF with overviews; or every camera (and every scene
of a strip) in one run, into a folder; or a block's products (SCENES) on one grid with their mosaic."""
from __future__ import annotations

from pyproj import CRS
from qgis.core import (QgsCoordinateReferenceSystem, QgsProcessingException, QgsProcessingOutputMultipleLayers,
                       QgsProcessingOutputRasterLayer, QgsProcessingParameterBoolean, QgsProcessingParameterCrs,
                       QgsProcessingParameterExtent, QgsProcessingParameterFolderDestination,
                       QgsProcessingParameterNumber, QgsProcessingParameterRasterDestination, QgsProcessingUtils)

from ...core.products.mosaic import MOSAIC_ORDERS, OFF_NADIR
from ...core.runs import orthorectify as use_case
from ...core.runs.scenes import SCENES as CORE_SCENES
from ..inputs import add_dem_parameters, add_scene_parameters, layer_crs, raster_file, raster_files, scene_or_block
from ..outputs import files_in_use, load_raster_stretched
from ..parameters import (CAMERA, DEM, INPUTS, RESAMPLING, SCENE, SCENES, SCHEDULER, RasterInput, camera_images,
                          enum_parameter, enum_value, resampling, scheduler, tr)
from .base import PushbroomAlgorithm


class OrthorectifyAlgorithm(PushbroomAlgorithm):
    ID = "orthorectify"
    NAME = "Orthorectify"
    GROUP, GROUP_ID = "Products", "products"
    INPUT, CRS_PARAM, RESOLUTION, RESAMPLING_PARAM, NODATA, EXTENT, OUTPUT = \
        "INPUT", "CRS", "RESOLUTION", RESAMPLING, "NODATA", "EXTENT", "OUTPUT"
    ALL_CAMERAS, INPUTS, ORTHO_FOLDER, ORTHOIMAGES, SCHEDULER, MOSAIC_ORDER, MOSAIC = \
        "ALL_CAMERAS", INPUTS, "ORTHO_FOLDER", "ORTHOIMAGES", SCHEDULER, "MOSAIC_ORDER", "MOSAIC"
    CORE_PARAMETERS = {"resolution": RESOLUTION, "scene": SCENE, "camera": CAMERA, "dem": DEM, "extent": EXTENT,
                       use_case.IMAGE: INPUT, use_case.IMAGES: INPUTS, use_case.OUTPUT: OUTPUT,
                       use_case.ORTHO_FOLDER: ORTHO_FOLDER, CORE_SCENES: SCENES, use_case.MOSAIC_ORDER: MOSAIC_ORDER}
    SCENE_OR_SCENES = ("orthorectify one scene", "orthorectify a block's products into one mosaic")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.addParameter(RasterInput(self.INPUT, tr("Raw image"), optional=True))
        self.addParameter(QgsProcessingParameterBoolean(self.ALL_CAMERAS, tr("Every camera of the scene"), False,
                                                        optional=True))
        self.addParameter(camera_images())
        add_scene_parameters(self, or_scenes=True)
        add_dem_parameters(self)
        self.addParameter(QgsProcessingParameterCrs(self.CRS_PARAM, tr("Output CRS"), optional=True))
        self.addParameter(QgsProcessingParameterNumber(self.RESOLUTION, tr("Pixel size (m)"),
                                                       QgsProcessingParameterNumber.Double, optional=True,
                                                       minValue=0.0))
        self.addParameter(resampling())
        self.addParameter(QgsProcessingParameterNumber(self.NODATA, tr("Nodata value"),
                                                       QgsProcessingParameterNumber.Double, 0.0))
        self.add_parameter(QgsProcessingParameterExtent(self.EXTENT, tr("Extent"), optional=True), advanced=True)
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, tr("Orthoimage"), optional=True))
        self.addParameter(QgsProcessingParameterFolderDestination(self.ORTHO_FOLDER, tr("Folder of the orthoimages"),
                                                                  optional=True))
        self.addParameter(enum_parameter(self.MOSAIC_ORDER, tr("Mosaic order (with SCENES)"), MOSAIC_ORDERS, OFF_NADIR,
                                         optional=True))
        self.add_parameter(scheduler(), advanced=True)
        self.addOutput(QgsProcessingOutputMultipleLayers(self.ORTHOIMAGES, tr("Orthoimages (ALL_CAMERAS, SCENES)")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.MOSAIC, tr("Mosaic (SCENES)")))
        self.show_only(self.INPUT, "ALL_CAMERAS", "INPUTS", "SCENE", "SCENES", "CAMERA", "DEM", self.CRS_PARAM)

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        scene, scenes = scene_or_block(self, parameters, context)
        every = bool(scenes) or self.parameterAsBool(parameters, self.ALL_CAMERAS, context)
        result = self.run_core(use_case.run, use_case.OrthoRequest(
            scene, self._output(parameters, context, every),
            self.terrain(parameters, context), raster_file(self, parameters, self.INPUT, context),
            self.parameterAsString(parameters, CAMERA, context),
            tuple(raster_files(self, parameters, INPUTS, context)) if every else None, self._crs(parameters, context),
            self.parameterAsDouble(parameters, self.RESOLUTION, context) or None, self._extent(parameters, context),
            enum_value(self, parameters, self.RESAMPLING_PARAM, context),
            self.parameterAsDouble(parameters, self.NODATA, context),
            self.parameterAsString(parameters, self.SCHEDULER, context).strip() or None,
            files_in_use(self, parameters, context), scenes,
            enum_value(self, parameters, self.MOSAIC_ORDER, context)), feedback)
        if scenes:
            load_raster_stretched(context, result.files[self.MOSAIC], tr("Mosaic"), self.MOSAIC)
        return result.files

    def _output(self, parameters, context, every: bool) -> str:
        """The orthoimage's file (a temporary one when not given), or with ALL_CAMERAS or SCENES the folder."""
        if not every:
            return (self.output_path(parameters, context, self.OUTPUT, "orthoimage.tif")
                    or QgsProcessingUtils.generateTempFilename("orthoimage.tif"))
        folder = self.parameterAsString(parameters, self.ORTHO_FOLDER, context)
        return QgsProcessingUtils.tempFolder() if not folder or folder == "TEMPORARY_OUTPUT" else folder

    def _extent(self, parameters, context):
        """EXTENT in a CRS, as QGIS converts it (None: not given)."""
        if not parameters.get(self.EXTENT):
            return None

        def extent_in(crs: CRS) -> tuple:
            rect = self.parameterAsExtent(parameters, self.EXTENT, context, QgsCoordinateReferenceSystem(crs.to_wkt()))
            return rect.xMinimum(), rect.yMinimum(), rect.xMaximum(), rect.yMaximum()
        return extent_in

    def _crs(self, parameters, context) -> CRS | None:
        """The output CRS as pyproj's, or None for the default (UTM); geographic CRSs refused."""
        qcrs = self.parameterAsCrs(parameters, self.CRS_PARAM, context)
        if not qcrs.isValid():
            if parameters.get(self.CRS_PARAM):
                raise QgsProcessingException(f"{self.CRS_PARAM}: unknown CRS {parameters.get(self.CRS_PARAM)!r}")
            return None
        crs = layer_crs(self.CRS_PARAM, qcrs)
        if not crs.is_projected:
            raise QgsProcessingException(f"{self.CRS_PARAM}: {qcrs.authid() or crs.name} is not a projected CRS; "
                                         "choose one in metres (e.g. the scene's UTM zone)")
        return crs
