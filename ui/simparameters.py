"""The parameters the simulation algorithms share (pushbroom:simulatescene, pushbroom:simulateblock):
one definition each, so that a name means one thing in every algorithm (tests/qgis/test_vocabulary.py)."""
from qgis.core import (QgsProcessingParameterBoolean, QgsProcessingParameterDefinition,
                       QgsProcessingParameterFolderDestination, QgsProcessingParameterNumber)

from ..simulation.presets import MIN_CUT
from .parameters import tr

SEED, N_GCPS, N_TIE_POINTS, IMAGE_NOISE, RENDER, IMAGE_SIZE, OUTPUT_FOLDER = \
    "SEED", "N_GCPS", "N_TIE_POINTS", "IMAGE_NOISE", "RENDER", "IMAGE_SIZE", "OUTPUT_FOLDER"


def _number(name: str, label: str, kind, default, low, high, help_text: str) -> QgsProcessingParameterNumber:
    parameter = QgsProcessingParameterNumber(name, label, kind, default, optional=name == IMAGE_SIZE, minValue=low,
                                             **({} if high is None else {"maxValue": high}))
    parameter.setHelp(help_text)
    return parameter


def seed() -> QgsProcessingParameterNumber:
    return _number(SEED, tr("Random seed"), QgsProcessingParameterNumber.Integer, 0, 0, None,
                   tr("Seed of the random errors, terrain, texture and point positions: the same seed gives the "
                      "same simulation."))


def n_gcps() -> QgsProcessingParameterNumber:
    return _number(N_GCPS, tr("Number of ground control points"), QgsProcessingParameterNumber.Integer, 200, 0,
                   2_000_000, tr("How many ground points (uniform over the ground the images see, on the terrain) to "
                                 "measure; each is measured in every camera (and every scene of a block) that sees "
                                 "it. Written to gcps.csv."))


def n_tie_points() -> QgsProcessingParameterNumber:
    return _number(N_TIE_POINTS, tr("Number of tie points"), QgsProcessingParameterNumber.Integer, 0, 0, 1_000_000,
                   tr("Ground points measured in every camera that sees them (at least two: presets with several "
                      "cameras, or the scenes of a block), without ground coordinates; written to tie_points.csv."))


def image_noise() -> QgsProcessingParameterNumber:
    return _number(IMAGE_NOISE, tr("Image measurement noise (px)"), QgsProcessingParameterNumber.Double, 0.3, 0.0,
                   100.0, tr("Standard deviation in pixels of the random error added to the measured image "
                             "coordinates (0: perfect measurements)."))


def render() -> QgsProcessingParameterBoolean:
    parameter = QgsProcessingParameterBoolean(RENDER, tr("Render the images"), defaultValue=False)
    parameter.setHelp(tr("Also write each camera's raw image (8-bit GeoTIFF, image_<CAMERA>.tif; <scene>.tif for "
                         "an RPC product) rendered from a known texture over the DEM, and reference.tif, a reference "
                         "orthoimage of the same ground for pushbroom:matchgcps. A 12246 × 12246 CBERS-02B scene "
                         "takes about 20 s and 80 MB."))
    return parameter


def image_size() -> QgsProcessingParameterNumber:
    parameter = _number(IMAGE_SIZE, tr("Cut the cameras to (px)"), QgsProcessingParameterNumber.Integer, 0, 0, None,
                        tr(f"0: the preset's full cameras. Otherwise each camera is cut to this many detectors and "
                           f"each scene to this many lines ({MIN_CUT} or more; presets whose cameras are one "
                           "detector line, e.g. th1_tlc and zy3_tlc), so a three-line block renders in seconds; the "
                           "preset's lens and CCD errors (px at the array end) are scaled by the cut's share of the "
                           "full array, so the distortion bends the images as in the full camera."))
    parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
    return parameter


def output_folder() -> QgsProcessingParameterFolderDestination:
    parameter = QgsProcessingParameterFolderDestination(OUTPUT_FOLDER, tr("Output folder"))
    parameter.setHelp(tr("Folder the simulated files are written to (created if missing). Files there of the names "
                         "the simulation writes are replaced only when an earlier simulation wrote them and they "
                         "were not changed since; a user's files are never replaced (the run stops)."))
    return parameter
