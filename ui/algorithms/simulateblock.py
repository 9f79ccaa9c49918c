"""pushbroom:simulateblock — a block of several independent scenes over one ground (tri-stereo,
a stereo pair, two dates, neighbouring strips, an RPC product of another date) with known truth."""
from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputMultipleLayers,
                       QgsProcessingOutputRasterLayer)

from ...simulation.block import simulate_block
from ...simulation.layouts import LAYOUT_MEANINGS, layout_members
from ...simulation.presets import PRESETS, cut_preset
from ..feedback import core_call, feedback_callbacks, processing_errors
from ..parameters import CHECK_FRACTION, PRESET, check_fraction, enum_parameter, enum_value, preset, tr
from ..simparameters import (IMAGE_NOISE, IMAGE_SIZE, N_GCPS, N_TIE_POINTS, RENDER, SEED, image_noise, image_size,
                             n_gcps, n_tie_points, output_folder, render, seed)
from .base import PushbroomAlgorithm


class SimulateBlockAlgorithm(PushbroomAlgorithm):
    ID = "simulateblock"
    NAME = "Simulate a block of scenes"
    GROUP, GROUP_ID = "Simulation", "simulation"
    HELP = ("Simulates a block of several independent scenes of one ground, as real projects hold them: a "
            "tri-stereo or a stereo pair of one pass, scenes of two dates, strips of neighbouring orbits, or a "
            "tri-stereo with a scene of another date delivered as an RPC product. Each scene is acquired by the "
            "preset's first camera with its own view, its own onboard errors (drawn independently) and, for "
            "another date, its own radiometry and changed land cover; every scene images the same terrain and, "
            "rendered, the same ground texture, so tie points can be matched between the scenes. Written to the "
            "output folder: one folder per scene (onboard_scene.json, true_scene.json, the raw image when "
            "rendered, <name>_RPC.TXT for an RPC product), the shared DEM (EGM96 geoid heights), gcps.csv and "
            "tie_points.csv with a scene column (one row per scene and camera an observation was measured in; "
            "true ground columns for checks), reference.tif (a reference orthoimage of the first scene's ground, "
            "when rendered) and block.json with every drawn error.")
    LAYOUT, SEED, N_GCPS, N_TIE_POINTS, IMAGE_NOISE, RENDER, IMAGE_SIZE = \
        "LAYOUT", SEED, N_GCPS, N_TIE_POINTS, IMAGE_NOISE, RENDER, IMAGE_SIZE
    OUTPUT_FOLDER = "OUTPUT_FOLDER"
    SCENES, TRUE_SCENES, IMAGES, GCPS, TIE_POINTS, DEM, REFERENCE, MANIFEST = \
        "SCENES", "TRUE_SCENES", "IMAGES", "GCPS", "TIE_POINTS", "DEM", "REFERENCE", "MANIFEST"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.addParameter(preset())
        self.addParameter(enum_parameter(self.LAYOUT, tr("Block"), LAYOUT_MEANINGS, "tristereo",
                                         tr("Which scenes the block holds.")))
        for parameter in (seed(), n_gcps(), n_tie_points(), image_noise(), render(), image_size()):
            self.addParameter(parameter)
        self.add_parameter(check_fraction(), advanced=True)
        folder = output_folder()
        self.addParameter(folder)
        self.addOutput(QgsProcessingOutputMultipleLayers(self.SCENES, tr("Onboard scene of each scene (scene JSON; "
                                                                         "the RPC file of an RPC product)")))
        self.addOutput(QgsProcessingOutputMultipleLayers(self.TRUE_SCENES, tr("True scene of each scene")))
        self.addOutput(QgsProcessingOutputMultipleLayers(self.IMAGES, tr("Raw image of each scene, when rendered")))
        self.addOutput(QgsProcessingOutputFile(self.GCPS, tr("Ground control points (CSV with a scene column)")))
        self.addOutput(QgsProcessingOutputFile(self.TIE_POINTS, tr("Tie points (CSV with a scene column)")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.DEM, tr("DEM (GeoTIFF, EGM96 geoid heights)")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.REFERENCE, tr("Reference orthoimage, when rendered")))
        self.addOutput(QgsProcessingOutputFile(self.MANIFEST, tr("Block settings and drawn errors (JSON)")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        spec = PRESETS[enum_value(self, parameters, PRESET, context)]
        size = self.parameterAsInt(parameters, self.IMAGE_SIZE, context)
        if size:
            with processing_errors(f"{self.IMAGE_SIZE}: "):
                spec = cut_preset(spec, size, size)
        members = layout_members(enum_value(self, parameters, self.LAYOUT, context), spec)
        progress, is_cancelled = feedback_callbacks(feedback)
        folder = self.parameterAsFileOutput(parameters, self.OUTPUT_FOLDER, context)
        result = core_call(simulate_block, members, folder, seed=self.parameterAsInt(parameters, self.SEED, context),
                           n_gcps=self.parameterAsInt(parameters, self.N_GCPS, context),
                           n_tie_points=self.parameterAsInt(parameters, self.N_TIE_POINTS, context),
                           image_noise=self.parameterAsDouble(parameters, self.IMAGE_NOISE, context),
                           render=self.parameterAsBool(parameters, self.RENDER, context),
                           check_fraction=self.parameterAsDouble(parameters, CHECK_FRACTION, context),
                           progress=progress, is_cancelled=is_cancelled)
        scenes, images = [], []
        for name, files in result.members.items():
            product = next(iter(files["rpc"].values())) if files.get("rpc") else files["onboard_scene"]
            scenes.append(str(product))
            images += [str(p) for p in files["images"].values()]
            feedback.pushInfo(f"scene {name}: {product}" + (f", image {', '.join(map(str, files['images'].values()))}"
                                                             if files["images"] else ""))
        return {self.OUTPUT_FOLDER: folder, self.SCENES: scenes,
                self.TRUE_SCENES: [str(f["true_scene"]) for f in result.members.values()], self.IMAGES: images,
                self.GCPS: str(result.gcps), self.TIE_POINTS: str(result.tie_points) if result.tie_points else None,
                self.DEM: str(result.dem), self.REFERENCE: str(result.reference) if result.reference else None,
                self.MANIFEST: str(result.manifest)}
