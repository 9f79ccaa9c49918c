"""pushbroom:orthorectify — the raw image resampled onto a map grid with the rigorous scene
model and a DEM: a tiled, compressed GeoTIFF with overviews."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError
from qgis.core import (QgsCoordinateReferenceSystem, QgsGeometry, QgsPointXY, QgsProcessingException,
                       QgsProcessingParameterCrs, QgsProcessingParameterExtent, QgsProcessingParameterNumber,
                       QgsProcessingParameterRasterDestination, QgsProcessingParameterRasterLayer, QgsRectangle)

from ...core.dem import ConstantHeight
from ...core.ortho import default_grid, orthorectify, scene_utm_crs
from ...core.products import footprints
from ..common import (CAMERA, DEM, SCENE, PushbroomAlgorithm, add_dem_parameters, add_scene_parameters, camera_for,
                      check_outputs, core_call, dem_from_parameters, feedback_callbacks, load_scene_for)
from ..parameters import RESAMPLING, enum_value, resampling, tr


class OrthorectifyAlgorithm(PushbroomAlgorithm):
    ID = "orthorectify"
    NAME = "Orthorectify"
    GROUP, GROUP_ID = "Products", "products"
    HELP = ("Resamples a raw pushbroom image onto a north-up map grid with the scene's rigorous model (onboard "
            "or adjusted) and a DEM. Every output pixel's image position is computed exactly on a coarse grid "
            "and densified within 0.01 px (checked per tile); cells along the seams of staggered CCD arrays "
            "are mapped pixel by pixel, so no seam is smeared. Works in tiles on all cores with bounded memory "
            "(raw images over 1 GiB are read window by window); "
            "writes a tiled, DEFLATE-compressed GeoTIFF with overviews and nodata, completely or not at all. "
            "With a DEM that covers only part of the scene, give an EXTENT inside it: pixels without a height "
            "are nodata and a warning gives their share of the footprint.")
    INPUT, CRS_PARAM, RESOLUTION, RESAMPLING_PARAM, NODATA, EXTENT, OUTPUT = \
        "INPUT", "CRS", "RESOLUTION", RESAMPLING, "NODATA", "EXTENT", "OUTPUT"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.add_parameter(QgsProcessingParameterRasterLayer(self.INPUT, tr("Raw image")),
                  tr("The scene's raw image (any GDAL format, any number of bands and data type), of the size the "
                  "scene's camera images, without georeferencing."))
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
        self.add_parameter(QgsProcessingParameterRasterDestination(self.OUTPUT, tr("Orthoimage")),
                  tr("GeoTIFF (tiled 512 x 512, DEFLATE, overviews, nodata set)."))


    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        output = self.output_path(parameters, context, self.OUTPUT, "orthoimage.tif")
        if Path(output).suffix.lower() not in (".tif", ".tiff"):
            raise QgsProcessingException(f"{self.OUTPUT}: the orthoimage is written as GeoTIFF; use a .tif file "
                                         f"(got {output})")
        check_outputs(self, parameters, context, {self.OUTPUT: [output]})
        layer = self.parameterAsRasterLayer(parameters, self.INPUT, context)
        if layer is None:
            raise QgsProcessingException(f"{self.INPUT}: no raw image given")
        image = layer.source().split("|")[0]
        scene = load_scene_for(SCENE, self.parameterAsFile(parameters, SCENE, context), feedback)
        camera = camera_for(CAMERA, scene, self.parameterAsString(parameters, CAMERA, context))
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
        grid = core_call(default_grid, scene, camera, surface, crs, resolution, extent)
        feedback.pushInfo(f"orthoimage {grid.cols} x {grid.rows} px at {grid.resolution:.3f} m in "
                          f"{grid.crs.to_string()}")
        progress, is_cancelled = feedback_callbacks(feedback)
        figures = core_call(orthorectify, scene, image, surface, output, camera, grid,
                            enum_value(self, parameters, self.RESAMPLING_PARAM, context),
                            self.parameterAsDouble(parameters, self.NODATA, context), progress=progress,
                            is_cancelled=is_cancelled)
        feedback.pushInfo(f"written in {figures['seconds']:.1f} s; image positions densified within "
                          f"{figures['densification_error_px']:.1e} px of the exact model")
        if figures["dem_gap_share"] > 0:
            feedback.pushWarning(f"{DEM}: the DEM gives no height for {100 * figures['dem_gap_share']:.1f} % "
                                 "of the image's footprint in the output; those pixels are nodata")
        return {self.OUTPUT: output}

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
