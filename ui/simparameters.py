"""The parameters the simulation algorithms share (pushbroom:simulatescene, pushbroom:simulateblock):
one definition each, so that a name means one thing in every algorithm (tests/qgis/test_vocabulary.py);
their help is in docs/parameters.md, section Simulation."""
from qgis.core import (QgsProcessingParameterBoolean, QgsProcessingParameterDefinition,
                       QgsProcessingParameterFolderDestination, QgsProcessingParameterNumber)

from .parameters import tr

SEED, N_GCPS, N_TIE_POINTS, IMAGE_NOISE, RENDER, IMAGE_SIZE, OUTPUT_FOLDER = \
    "SEED", "N_GCPS", "N_TIE_POINTS", "IMAGE_NOISE", "RENDER", "IMAGE_SIZE", "OUTPUT_FOLDER"
# pushbroom:simulateblock's regions (LAYOUT region, rpc_region)
STRIPS, PRODUCTS_PER_STRIP, SIDE_LAP, FORWARD_OVERLAP, TIES_PER_PRODUCT = \
    "STRIPS", "PRODUCTS_PER_STRIP", "SIDE_LAP", "FORWARD_OVERLAP", "TIES_PER_PRODUCT"


def _number(name: str, label: str, kind, default, low, high) -> QgsProcessingParameterNumber:
    return QgsProcessingParameterNumber(name, label, kind, default, optional=name == IMAGE_SIZE, minValue=low,
                                        **({} if high is None else {"maxValue": high}))


def seed() -> QgsProcessingParameterNumber:
    return _number(SEED, tr("Random seed"), QgsProcessingParameterNumber.Integer, 0, 0, None)


def n_gcps() -> QgsProcessingParameterNumber:
    return _number(N_GCPS, tr("Number of ground control points"), QgsProcessingParameterNumber.Integer, 200, 0,
                   2_000_000)


def n_tie_points() -> QgsProcessingParameterNumber:
    return _number(N_TIE_POINTS, tr("Number of tie points"), QgsProcessingParameterNumber.Integer, 0, 0, 1_000_000)


def image_noise() -> QgsProcessingParameterNumber:
    return _number(IMAGE_NOISE, tr("Image measurement noise (px)"), QgsProcessingParameterNumber.Double, 0.3, 0.0,
                   100.0)


def render() -> QgsProcessingParameterBoolean:
    return QgsProcessingParameterBoolean(RENDER, tr("Render the images"), defaultValue=False)


def image_size() -> QgsProcessingParameterNumber:
    """IMAGE_SIZE: 0 or at least simulation.presets.MIN_CUT (its help says so)."""
    parameter = _number(IMAGE_SIZE, tr("Cut the cameras to (px)"), QgsProcessingParameterNumber.Integer, 0, 0, None)
    parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
    return parameter


def output_folder() -> QgsProcessingParameterFolderDestination:
    return QgsProcessingParameterFolderDestination(OUTPUT_FOLDER, tr("Output folder"))


def region_parameters() -> list[QgsProcessingParameterNumber]:
    """STRIPS, PRODUCTS_PER_STRIP, SIDE_LAP, FORWARD_OVERLAP, TIES_PER_PRODUCT (defaults of
    simulation.region.RegionLayout and simulation.rpcregion.RegionSettings; limits of the layout's checks)."""
    whole, share = QgsProcessingParameterNumber.Integer, QgsProcessingParameterNumber.Double
    return [_number(STRIPS, tr("Region: strips"), whole, 3, 1, 1000),
            _number(PRODUCTS_PER_STRIP, tr("Region: products per strip"), whole, 4, 1, 1000),
            _number(SIDE_LAP, tr("Region: side-lap (share of a product's width)"), share, 0.2, 0.02, 0.6),
            _number(FORWARD_OVERLAP, tr("Region: forward overlap (share of a product's length)"), share, 0.15, 0.02,
                    0.6),
            _number(TIES_PER_PRODUCT, tr("Region without images: tie observations per product"), whole, 2000, 0,
                    1_000_000)]
