"""Inputs untouched (issue 28, finding 10; issue 30): every algorithm of the provider, run on inputs each in
a folder of its own — the scene files, the raw images, the DEM, the reference orthoimage, the GCP, tie-point
and line files, the scenes of a block, an RPC product as delivered (its image beside its _RPC.TXT) and inputs
given as VRTs — leaves each of those folders exactly as it was: the same files (no ``.aux.xml`` of GDAL's
PAM or of QGIS's statistics, no journal of a GeoPackage), each byte for byte the same (statistics were once
written into an input VRT). Runs that are refused (a VRT of too few rows, a DEM too big to read whole) must
leave them so too.

The algorithms are enumerated from the provider: one that has no case here fails the test. A graphical model
of the provider is covered by a case of its own or, when it takes no input file (the simulate-and-process
models), by the cases of each of its steps.
"""
from __future__ import annotations

import gc
import shutil
from dataclasses import dataclass
from pathlib import Path

import pytest
from osgeo import gdal
from qgis.core import QgsProcessingException, QgsProcessingFeedback, QgsProject, QgsRasterLayer

import processing
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate
from tests.support.hostile import huge_vrt, snapshot
from tests.support.matchscene import MINI_TLC

gdal.UseExceptions()

NAMES = ("nad", "fwd", "bwd")  # the tri-stereo scenes of the block, by their folders
CAMERAS = ("NAD", "FWD", "BWD")  # the three-line scene's cameras
INPUT_FOLDERS = ("scene", "images", "dem", "reference", "gcps", "ties", "lines", "points", "block", "block_images",
                 "block_gcps", "block_ties", "rpc", "vrt")


@pytest.fixture(scope="module")
def made(provider, tmp_path_factory) -> Path:
    """The inputs of every case, each kind in a folder of its own: a rendered three-line scene (MINI_TLC of
    tests/support/matchscene.py: roads, GCPs, tie points) and a rendered block (tri-stereo and an RPC product of another date), the
    GCP, tie-point and line layers imported from them, and three VRTs (a raw image cut short, an RGB raster
    of the three cameras' images, the DEM at 1/300 of its pixel size: 165 000 x 157 500 pixels)."""
    tmp = tmp_path_factory.mktemp("made")
    sim = simulate(MINI_TLC, tmp / "sim", seed=7, render=True, gcp_settings=GcpSettings(n_gcps=20, n_tie_points=30),
                   n_lines=4)
    block = processing.run("pushbroom:simulateblock", {
        "PRESET": "th1_tlc", "LAYOUT": "tristereo_and_other_date", "SEED": 2, "N_GCPS": 20, "N_TIE_POINTS": 30,
        "IMAGE_SIZE": 500, "RENDER": True, "OUTPUT_FOLDER": str(tmp / "block")})
    root = tmp / "inputs"
    for folder in INPUT_FOLDERS:
        (root / folder).mkdir(parents=True)
    shutil.copy(sim.onboard_scene, root / "scene" / "scene.json")
    for path in sim.images.values():
        shutil.copy(path, root / "images")
    shutil.copy(sim.dem, root / "dem" / "dem.tif")
    shutil.copy(sim.reference, root / "reference" / "reference.tif")
    shutil.copy(sim.gcps, root / "gcps" / "gcps.csv")
    shutil.copy(sim.tie_points, root / "ties" / "tie_points.csv")
    shutil.copy(sim.lines, root / "lines" / "lines.gpkg")
    (root / "points" / "pixels.csv").write_text("id,col,row\n" + "".join(f"{i},{40 + 40 * i},{30 + 35 * i}\n"
                                                                       for i in range(10)))
    for name in NAMES:
        (root / "block" / name).mkdir()
        (root / "block_images" / name).mkdir()
        shutil.copy(tmp / "block" / name / "onboard_scene.json", root / "block" / name)
        shutil.copy(tmp / "block" / name / "image_NAD.tif", root / "block_images" / name)
    for name in ("date2.tif", "date2_RPC.TXT"):  # the RPC product as delivered: the image beside its RPC
        shutil.copy(tmp / "block" / "date2" / name, root / "rpc")
    shutil.copy(block["GCPS"], root / "block_gcps" / "gcps.csv")
    shutil.copy(block["TIE_POINTS"], root / "block_ties" / "tie_points.csv")
    inputs = Inputs(root)
    processing.run("pushbroom:importgcps", {"SCENE": inputs.scene, "INPUT_FILE": inputs.gcps_csv, "Z_FIELD": "h",
                                            "Z_DATUM": "ellipsoid", "OUTPUT": inputs.gcps})
    processing.run("pushbroom:importtiepoints", {"SCENE": inputs.scene, "INPUT_FILE": str(root / "ties" /
                                                                                         "tie_points.csv"),
                                                 "OUTPUT": inputs.ties})
    processing.run("pushbroom:importlines", {"SCENE": inputs.scene, "INPUT": inputs.layer("ground_lines"),
                                             "IMAGE_LINES": inputs.layer("image_lines"), "HEIGHT_SOURCE": "z",
                                             "Z_DATUM": "ellipsoid", "OUTPUT": inputs.control_lines})
    processing.run("pushbroom:importgcps", {"SCENES": inputs.scenes, "INPUT_FILE": str(root / "block_gcps" /
                                                                                      "gcps.csv"),
                                            "Z_FIELD": "h", "Z_DATUM": "ellipsoid", "OUTPUT": inputs.block_gcps})
    gdal.Translate(str(root / "vrt" / "short.vrt"), inputs.image("NAD"), format="VRT", srcWin=[0, 0, 1500, 300])
    gdal.BuildVRT(str(root / "vrt" / "rgb.vrt"), [inputs.image(c) for c in CAMERAS], separate=True)
    huge_vrt(root / "dem" / "dem.tif", root / "vrt" / "huge.vrt", factor=300)
    QgsProject.instance().removeAllMapLayers()
    return root


@dataclass
class Inputs:
    """The paths of a case's inputs under ``root`` (a copy of ``made``) and of its output folder."""
    root: Path

    def __post_init__(self):
        r = self.root
        self.scene, self.dem, self.reference = str(r / "scene" / "scene.json"), str(r / "dem" / "dem.tif"), \
            str(r / "reference" / "reference.tif")
        self.gcps_csv, self.gcps = str(r / "gcps" / "gcps.csv"), str(r / "gcps" / "gcps.gpkg")
        self.ties, self.lines = str(r / "ties" / "ties.gpkg"), str(r / "lines" / "lines.gpkg")
        self.control_lines, self.pixels = str(r / "lines" / "control_lines.gpkg"), str(r / "points" / "pixels.csv")
        self.scenes = [str(r / "block" / n / "onboard_scene.json") for n in NAMES] + [str(r / "rpc" /
                                                                                         "date2_RPC.TXT")]
        self.block_images = [str(r / "block_images" / n / "image_NAD.tif") for n in NAMES] + [str(r / "rpc" /
                                                                                                 "date2.tif")]
        self.block_gcps = str(r / "block_gcps" / "gcps.gpkg")
        self.block_ties = str(r / "block_ties" / "tie_points.csv")  # a CSV table given as the layer TIE_POINTS
        self.out = r.parent / "out"

    def image(self, camera: str) -> str:
        return str(self.root / "images" / f"image_{camera}.tif")

    def vrt(self, name: str) -> str:
        return str(self.root / "vrt" / name)

    def layer(self, name: str) -> str:
        return f"{self.lines}|layername={name}"

    def output(self, name: str) -> str:
        return str(self.out / name)


def _ortho(f: Inputs, **kw) -> dict:
    return {"INPUT": f.image("NAD"), "SCENE": f.scene, "CAMERA": "NAD", "DEM": f.dem, "RESOLUTION": 20.0,
            "OUTPUT": f.output("ortho.tif"), **kw}


def _match(f: Inputs, **kw) -> dict:
    return {"DEM": f.dem, "SPACING": 100.0, "SEARCH_RANGE": 300.0, "OUTPUT": f.output("matched.gpkg"), **kw}


# (case, algorithm id, parameters of the case's Inputs, None for a run that succeeds or the texts its refusal holds)
CASES = [
    ("simulatescene", "pushbroom:simulatescene",
     lambda f: {"PRESET": "th1_tlc", "IMAGE_SIZE": 500, "N_GCPS": 5, "OUTPUT_FOLDER": f.output("sim")}, None),
    ("simulateblock", "pushbroom:simulateblock",
     lambda f: {"PRESET": "th1_tlc", "LAYOUT": "stereo_pair", "IMAGE_SIZE": 500, "N_GCPS": 5,
                "OUTPUT_FOLDER": f.output("block")}, None),
    ("importgcps", "pushbroom:importgcps",
     lambda f: {"SCENE": f.scene, "INPUT_FILE": f.gcps_csv, "HEIGHT_SOURCE": "dem", "DEM": f.dem,
                "OUTPUT": f.output("gcps.gpkg")}, None),
    ("importgcps-layer", "pushbroom:importgcps",
     lambda f: {"SCENE": f.scene, "INPUT": f.gcps, "Z_DATUM": "ellipsoid", "OUTPUT": f.output("gcps.gpkg")}, None),
    ("importgcps-block", "pushbroom:importgcps",
     lambda f: {"SCENES": f.scenes, "INPUT_FILE": str(f.root / "block_gcps" / "gcps.csv"), "Z_FIELD": "h",
                "Z_DATUM": "ellipsoid", "OUTPUT": f.output("gcps.gpkg")}, None),
    ("importtiepoints", "pushbroom:importtiepoints",
     lambda f: {"SCENE": f.scene, "INPUT_FILE": str(f.root / "ties" / "tie_points.csv"),
                "OUTPUT": f.output("ties.gpkg")}, None),
    ("importlines", "pushbroom:importlines",
     lambda f: {"SCENE": f.scene, "INPUT": f.layer("ground_lines"), "IMAGE_LINES": f.layer("image_lines"),
                "HEIGHT_SOURCE": "dem", "DEM": f.dem, "OUTPUT": f.output("lines.gpkg")}, None),
    ("matchgcps", "pushbroom:matchgcps",
     lambda f: _match(f, INPUT=f.image("NAD"), SCENE=f.scene, CAMERA="NAD", REFERENCE=f.reference), None),
    ("matchtiepoints", "pushbroom:matchtiepoints",
     lambda f: _match(f, SCENE=f.scene, INPUTS=[f.image(c) for c in CAMERAS]), None),
    ("matchtiepoints-block", "pushbroom:matchtiepoints",
     lambda f: _match(f, SCENES=f.scenes, INPUTS=f.block_images), None),
    ("bundleadjust", "pushbroom:bundleadjust",
     lambda f: {"SCENE": f.scene, "GCPS": f.gcps, "TIE_POINTS": f.ties, "LINES": f.control_lines,
                "OUTPUT_SCENE": f.output("adjusted.json"), "OUTPUT_REPORT": f.output("report.html"),
                "OUTPUT_GCPS": f.output("gcps.gpkg"), "OUTPUT_TIE_POINTS": f.output("ties.gpkg")}, None),
    ("bundleadjust-block", "pushbroom:bundleadjust",
     lambda f: {"SCENES": f.scenes, "GCPS": f.block_gcps, "TIE_POINTS": f.block_ties, "RPC_SIGMA": 10.0,
                "OUTPUT_FOLDER": f.output("adjusted")}, None),
    ("groundtoimage", "pushbroom:groundtoimage",
     lambda f: {"SCENE": f.scene, "INPUT": f.gcps, "USE_Z": False, "DEM": f.dem,
                "OUTPUT": f.output("pixels.gpkg")}, None),
    ("imagetoground", "pushbroom:imagetoground",
     lambda f: {"SCENE": f.scene, "INPUT": f.pixels, "DEM": f.dem, "OUTPUT": f.output("ground.gpkg")}, None),
    ("footprint", "pushbroom:footprint",
     lambda f: {"SCENE": f.scene, "DEM": f.dem, "OUTPUT": f.output("footprint.gpkg")}, None),
    ("orthorectify", "pushbroom:orthorectify", _ortho, None),
    ("orthorectify-all-cameras", "pushbroom:orthorectify",
     lambda f: _ortho(f, INPUT=None, CAMERA=None, OUTPUT=None, ALL_CAMERAS=True, INPUTS=[f.image(c) for c in CAMERAS],
                      ORTHO_FOLDER=f.output("orthos")), None),
    ("orthorectify-rpc-product", "pushbroom:orthorectify",
     lambda f: _ortho(f, INPUT=f.block_images[-1], SCENE=f.scenes[-1], CAMERA=None), None),
    ("exportrpc", "pushbroom:exportrpc",
     lambda f: {"SCENE": f.scene, "CAMERA": "NAD", "DEM": f.dem, "IMAGE": f.image("NAD"),
                "OUTPUT": f.output("image_NAD_RPC.TXT")}, None),
    ("sensorcorrect", "pushbroom:sensorcorrect",
     lambda f: {"INPUT": f.image("NAD"), "SCENE": f.scene, "CAMERA": "NAD", "DEM": f.dem,
                "OUTPUT": f.output("sc.tif"), "OUTPUT_SCENE": f.output("sc.json")}, None),
    ("preparedigitising", "pushbroom:preparedigitising",
     lambda f: {"INPUT": f.image("NAD"), "SCENE": f.scene, "CAMERA": "NAD", "OUTPUT": f.output("display.vrt"),
                "OUTPUT_LINES": f.output("image_lines.gpkg")}, None),
    ("snaplines", "pushbroom:snaplines",
     lambda f: {"INPUT": f.image("NAD"), "IMAGE_LINES": f.layer("image_clicks"), "OUTPUT": f.output("snapped.gpkg")},
     None),
    ("model-adjust-with-lines", "pushbroom:Adjust with GCPs and control lines",
     lambda f: {"SCENE": f.scene, "GCP_FILE": f.gcps_csv, "GROUND_LINES": f.layer("ground_lines"),
                "IMAGE_LINES": f.layer("image_lines"), "lines:Control lines": f.output("control_lines.gpkg"),
                "adjust:Adjusted scene": f.output("a.json"), "adjust:Adjustment report": f.output("report.html")},
     None),
    # inputs given as VRTs: GDAL wrote the statistics QGIS asked for into them
    ("orthorectify-short-vrt", "pushbroom:orthorectify", lambda f: _ortho(f, INPUT=f.vrt("short.vrt")),
     ["INPUT", "300"]),
    ("orthorectify-rgb-vrt", "pushbroom:orthorectify", lambda f: _ortho(f, INPUT=f.vrt("rgb.vrt")), None),
    ("preparedigitising-rgb-vrt", "pushbroom:preparedigitising",
     lambda f: {"INPUT": f.vrt("rgb.vrt"), "SCENE": f.scene, "CAMERA": "NAD", "OUTPUT": f.output("display.vrt")},
     None),
    ("footprint-huge-vrt-dem", "pushbroom:footprint",
     lambda f: {"SCENE": f.scene, "DEM": f.vrt("huge.vrt"), "OUTPUT": f.output("footprint.gpkg")}, None),
    ("orthorectify-huge-vrt-dem", "pushbroom:orthorectify", lambda f: _ortho(f, DEM=f.vrt("huge.vrt")),
     ["huge.vrt", "coarser DEM"]),
]

# Models that take no input file: they simulate their inputs and run steps that each have cases here
COVERED_BY_STEPS = ("pushbroom:Simulate, adjust, orthorectify and export RPC",
                    "pushbroom:Simulate, match GCPs, adjust, orthorectify and export RPC",
                    "pushbroom:Three-line block: simulate, match tie points, adjust")


@pytest.fixture
def inputs(made, tmp_path) -> Inputs:
    """A fresh copy of the inputs (tmp_path/inputs) and an empty output folder (tmp_path/out)."""
    shutil.copytree(made, tmp_path / "inputs", symlinks=True)
    (tmp_path / "out").mkdir()
    yield Inputs(tmp_path / "inputs")
    QgsProject.instance().removeAllMapLayers()


def _given(params: dict) -> dict:
    return {k: v for k, v in params.items() if v is not None}


def _changes(before: dict, after: dict) -> dict:
    """{'added': [...], 'removed': [...], 'changed': [...]} between two snapshots (relative paths)."""
    return {"added": sorted(set(after) - set(before)), "removed": sorted(set(before) - set(after)),
            "changed": sorted(k for k in set(before) & set(after) if before[k] != after[k])}


def _run(alg_id: str, params: dict, refusal) -> None:
    if refusal is None:
        processing.run(alg_id, params, feedback=QgsProcessingFeedback())
        return
    with pytest.raises(QgsProcessingException) as info:
        processing.run(alg_id, params, feedback=QgsProcessingFeedback())
    for text in refusal:
        assert text.lower() in str(info.value).lower(), (text, str(info.value))


def _load_outputs(folder: Path) -> None:
    """Every raster written to ``folder`` loaded as a QGIS layer and dropped, as the toolbox loads the
    outputs of a run (QGIS computes the statistics of each: a VRT over an input passed them on to it)."""
    for path in sorted(folder.rglob("*")):
        if path.suffix.lower() in (".tif", ".vrt"):
            assert QgsProject.instance().addMapLayer(QgsRasterLayer(str(path), path.name)).isValid(), path
    QgsProject.instance().removeAllMapLayers()
    gc.collect()


def _assert_unchanged(before: dict, inputs: Inputs) -> None:
    changes = _changes(before, snapshot(inputs.root))
    assert not any(changes.values()), {k: [str(Path(p).relative_to(inputs.root)) for p in v] for k, v in changes.items()}


@pytest.mark.parametrize("alg_id, make, refusal", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_no_file_appears_beside_an_input_and_none_changes(inputs, alg_id, make, refusal):
    """Through processing.run, then with every raster output loaded in QGIS."""
    before = snapshot(inputs.root)
    _run(alg_id, _given(make(inputs)), refusal)
    gc.collect()
    _assert_unchanged(before, inputs)
    _load_outputs(inputs.out)
    _assert_unchanged(before, inputs)


CLI_CASES = ("orthorectify-all-cameras", "matchgcps", "matchtiepoints-block",
             "preparedigitising", "orthorectify-rgb-vrt", "footprint-huge-vrt-dem", "orthorectify-short-vrt")


@pytest.mark.parametrize("alg_id, make, refusal", [c[1:] for c in CASES if c[0] in CLI_CASES], ids=CLI_CASES)
def test_no_file_appears_beside_an_input_from_the_command_line(qgis_process, inputs, alg_id, make, refusal):
    """Through qgis_process, whose layers are dropped (and their files closed) when it ends: each kind of
    raster input (DEM, raw image, several images, reference, the images of a block, VRTs)."""
    before = snapshot(inputs.root)
    done = qgis_process("run", alg_id, "--", *(f"{k}={v}" for k, values in _given(make(inputs)).items()
                                               for v in (values if isinstance(values, list) else [values])))
    assert (done.returncode == 0) == (refusal is None), done.stdout + done.stderr
    for text in refusal or ():
        assert text.lower() in (done.stdout + done.stderr).lower(), (text, done.stdout + done.stderr)
    _assert_unchanged(before, inputs)


def test_every_algorithm_of_the_provider_has_a_case(provider):
    """A new algorithm (or graphical model) fails here until it has a case above."""
    cased = {c[1] for c in CASES}
    missing = []
    for alg in provider.algorithms():
        if alg.id() in COVERED_BY_STEPS:
            steps = {child.algorithmId() for child in alg.childAlgorithms().values()}
            missing += [f"{alg.id()} (step {s})" for s in sorted(steps - cased)]
        elif alg.id() not in cased:
            missing.append(alg.id())
    assert not missing, f"algorithms with no case of inputs untouched: {missing}"
    assert len(provider.algorithms()) == 20
