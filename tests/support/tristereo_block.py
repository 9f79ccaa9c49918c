"""The simulated tri-stereo of the Processing tests of blocks (tests/qgis/test_bundleadjust_block*.py):
pushbroom:simulateblock's TH-1 nadir, forward and backward scenes of one pass, each its own onboard
errors, 600 x 600 px, not rendered; how far a scene is from the truth; and a graphical model that
adjusts it."""
from __future__ import annotations

import numpy as np
from qgis.core import (QgsProcessing, QgsProcessingModelAlgorithm, QgsProcessingModelChildAlgorithm,
                       QgsProcessingModelChildParameterSource, QgsProcessingModelOutput, QgsProcessingModelParameter,
                       QgsProcessingParameterMultipleLayers, QgsProcessingParameterVectorLayer)

import processing
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene

NAMES = ("nad", "fwd", "bwd")  # the scenes of LAYOUT tristereo, by their folders
# one trajectory correction per scene: bias and drift of position and attitude, the onboard sigmas as
# the simulated errors of th1_tlc (position ~10 m, attitude ~40 arcsec)
ADJUST = {"POSITION_ORDER": 1, "ATTITUDE_ORDER": 1, "POSITION_SIGMA": 20.0, "ATTITUDE_SIGMA": 60.0}


def simulate_tristereo(folder, n_gcps: int) -> dict:
    """The block simulated into ``folder`` (seed 3, 60 tie points, a quarter of the GCPs check
    points): pushbroom:simulateblock's outputs."""
    return processing.run("pushbroom:simulateblock", {
        "PRESET": "th1_tlc", "LAYOUT": "tristereo", "IMAGE_SIZE": 600, "RENDER": False, "SEED": 3,
        "N_GCPS": n_gcps, "N_TIE_POINTS": 60, "CHECK_FRACTION": 0.25, "OUTPUT_FOLDER": str(folder)})


def check_px(block, scene_paths, names=NAMES) -> dict:
    """{scene: RMS (px)} of a 9 x 9 lattice over each scene's image, its true ground (on the DEM)
    projected through the given scene against the lattice."""
    dem = Dem(block["DEM"], "geoid")
    out = {}
    for name, true_path, path in zip(names, block["TRUE_SCENES"], scene_paths):
        true, scene = load_scene(true_path), load_scene(path)
        cam = true.cameras[0]
        col, row = (a.ravel() for a in np.meshgrid(np.linspace(10, cam.cols - 10, 9), np.linspace(10, cam.rows - 10, 9)))
        col2, row2 = scene.ground_to_image(true.image_to_ground_dem(col, row, dem, 0), 0)
        out[name] = float(np.sqrt(np.mean((col2 - col) ** 2 + (row2 - row) ** 2)))
    return out


def block_model(static: dict | None = None, gcps: bool = True) -> QgsProcessingModelAlgorithm:
    """A graphical model of one step: bundleadjust of the model's input 'scenes' (SCENES) with the
    inputs 'gcps' (unless not ``gcps``) and 'ties', its folder the model's output 'adjusted'; the
    other parameters ADJUST's, ``static``'s or their defaults, as static values."""
    model = QgsProcessingModelAlgorithm("block adjustment", "tests")
    inputs = {"SCENES": QgsProcessingParameterMultipleLayers("scenes", "scenes", QgsProcessing.TypeFile),
              "TIE_POINTS": QgsProcessingParameterVectorLayer("ties", "ties", [QgsProcessing.TypeVector])}
    if gcps:
        inputs["GCPS"] = QgsProcessingParameterVectorLayer("gcps", "gcps", [QgsProcessing.TypeVectorPoint])
    child = QgsProcessingModelChildAlgorithm("pushbroom:bundleadjust")
    child.setChildId("adjust")
    for name, parameter in inputs.items():
        model.addModelParameter(parameter, QgsProcessingModelParameter(parameter.name()))
        child.addParameterSources(name, [QgsProcessingModelChildParameterSource.fromModelParameter(parameter.name())])
    given = {**ADJUST, **(static or {})}
    for definition in child.algorithm().parameterDefinitions():  # the rest at their defaults, as the modeler sets them
        value = given.get(definition.name(), definition.defaultValue())
        if definition.name() not in child.parameterSources() and not definition.isDestination() and value is not None:
            child.addParameterSources(definition.name(), [QgsProcessingModelChildParameterSource.fromStaticValue(value)])
    output = QgsProcessingModelOutput("adjusted")
    output.setChildOutputName("OUTPUT_FOLDER")
    child.setModelOutputs({"adjusted": output})
    model.addChildAlgorithm(child)
    model.updateDestinationParameters()
    return model
