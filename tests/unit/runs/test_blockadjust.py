"""core.runs.blockadjust: the use case behind pushbroom:bundleadjust with SCENES, on the simulated block
of tests/support/simulated_block.py (three TH-1 three-line scenes cut to 500 x 500 px, their own
trajectory errors, tie points in every camera, 0.3 px) with 4 GCPs near the corners of S1: the scene
files, the GCP and tie-point GeoPackages as the user gives them, the folder written, the figures the
core's block adjustment gives, and refusals that name their input and leave no folder behind."""
import json
from dataclasses import replace

import numpy as np
import pytest

from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import save_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations import tiepoints
from pushbroom_adjust.core.runs import bundleadjust as use_case
from pushbroom_adjust.core.runs.adjustinputs import AdjustRequest, LayerFile
from pushbroom_adjust.core.runs.blockadjust import planned_files
from tests.support.simulated_block import NOISE, SETTINGS, SimulatedBlock


class Block(SimulatedBlock):
    """The simulated block with 4 GCPs near the corners of S1's nadir image, 0.3 px, ground sigmas 0.1 / 0.2 m."""

    def add_control(self, ref) -> None:
        ground = ref.image_to_ground(np.array([100.0, 400, 100, 400]), np.array([100.0, 100, 400, 400]),
                                     np.array([400.0, 800, 600, 500]), 0)
        m = self.measure(ground)
        lon, lat, h = ecef_to_geodetic(ground[m["point"]])
        self.gcps = G.GcpTable(np.char.add("G", m["point"].astype(str)), "control", m["camera"], m["col"], m["row"],
                               lon, lat, h, NOISE, 0.1, 0.2, scene=m["scene"])


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> dict:
    """The block and its files: a scene JSON per onboard scene (S1.json...), gcps.gpkg, ties.gpkg."""
    folder = tmp_path_factory.mktemp("runs_block")
    sim = Block(folder)
    files = {}
    for name, scene in sim.onboard.items():
        files[name] = str(folder / f"{name}.json")
        save_scene(scene, files[name])
    G.write_gpkg(sim.gcps, folder / "gcps.gpkg")
    tiepoints.write_gpkg(sim.ties, folder / "ties.gpkg")
    return {"sim": sim, "files": files, "gcps": str(folder / "gcps.gpkg"), "ties": str(folder / "ties.gpkg")}


def request(block, folder, **fields) -> AdjustRequest:
    return AdjustRequest(**{"scenes": block["files"], "gcps": LayerFile(block["gcps"]),
                            "ties": LayerFile(block["ties"]), "settings": SETTINGS, "folder": str(folder), **fields})


def test_the_block_written_is_the_core_s_and_near_the_truth(block, tmp_path):
    folder = tmp_path / "out"  # created by the run
    result = use_case.run(request(block, folder))
    scenes = [str(folder / f"{name}_adjusted.json") for name in ("S1", "S2", "S3")]
    assert result.files["OUTPUT_FOLDER"] == str(folder) and result.files["ADJUSTED_SCENES"] == scenes
    assert result.files["OUTPUT_REPORT_JSON"] == str(folder / "block_report.json")
    assert all(result.files[name] is None for name in ("OUTPUT_SCENE", "OUTPUT_REPORT", "OUTPUT_GCPS", "OUTPUT_RPC"))
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        ["S1_adjusted.json", "S2_adjusted.json", "S3_adjusted.json", "block_report.html", "block_report.json",
         "adjusted_gcps.gpkg", "adjusted_tie_points.gpkg"])
    # the core's block adjustment of the same tables (read back from the GeoPackages) gives the same solution
    sim = block["sim"]
    direct = adjust_block(sim.onboard, G.read_gpkg(block["gcps"]), tiepoints.read_gpkg(block["ties"]), SETTINGS)
    report = result.figures["report"]
    assert report["block"]["sigma0"] == direct.report["block"]["sigma0"]
    assert 0.7 < report["block"]["sigma0"] < 1.3 and report["block"]["tie_rmse_px"] < 0.5
    assert json.loads((folder / "block_report.json").read_text())["block"]["sigma0"] == pytest.approx(
        report["block"]["sigma0"])
    # the written scenes against the truth (49 check ground points): Measured, onboard 22.5, 23.3, 24.2 px,
    # adjusted 0.12, 0.10, 0.13 px; sigma0 0.95, tie RMS 0.33 px
    for name, path in zip(("S1", "S2", "S3"), scenes):
        onboard, adjusted = sim.check_px(name, sim.onboard[name]), sim.check_px(name, load_scene(path))
        assert onboard > 20.0 and adjusted < 0.25, (name, onboard, adjusted)
    texts = [line.text for line in result.lines]
    assert [t for t in texts if t.startswith("scene S")][:3] == [f"scene {n}: {p}" for n, p in block["files"].items()]


def test_write_rpcs_plans_one_rpc_per_camera_of_a_rigorous_scene(block, tmp_path):
    planned = planned_files(tmp_path, block["sim"].onboard, True, True, False)
    assert sorted(p.name for p in planned["rpcs"].values()) == sorted(
        f"{s}_{c}_RPC.TXT" for s in ("S1", "S2", "S3") for c in ("NAD", "FWD", "BWD"))
    assert planned["refined"] == {} and planned["ties"] == "" and planned["gcps"] == tmp_path / "adjusted_gcps.gpkg"


@pytest.mark.parametrize("fields, parameter, message", [
    ({"scenes": "one"}, "scenes", r"^1 scene given; a block needs two or more"),
    ({"outputs": {"OUTPUT_GCPS": "g.gpkg"}}, "OUTPUT_GCPS",
     r"^with SCENES the block's outputs go to OUTPUT_FOLDER \(it writes adjusted_gcps.gpkg there\)"),
    ({"scene_sigmas": ("S9", "5", "", "")}, "settings.scene_sigmas",
     r"^SCENE_SIGMAS: row 1: scene 'S9' is not in SCENES; expected one of the block's scenes \(S1, S2, S3"),
    ({"scene_sigmas": ("S1", "", "", "2")}, "settings.scene_sigmas",
     r"^SCENE_SIGMAS: scene 'S1' is a rigorous scene: RPC_SIGMA is the prior of RPC products"),
    ({"ties": "S1-S2"}, "ties", r"^no tie point joins the scenes of these groups to each other: S1, S2; S3"),
    ({"settings": replace(SETTINGS, interior="S1/PAN.*")}, "settings.interior", r"This scene has camera S1/NAD"),
])
def test_refusals_name_their_input_and_leave_no_folder(block, tmp_path, fields, parameter, message):
    if fields.get("scenes") == "one":
        fields["scenes"] = {"S1": block["files"]["S1"]}
    if fields.get("ties") == "S1-S2":  # tie points between S1 and S2 only; S3 held by a GCP of its own
        ties = block["sim"].ties
        path = tmp_path / "ties_s1s2.gpkg"
        tiepoints.write_gpkg(ties.select(ties.scene != "S3"), path)
        gcps = block["sim"].gcps
        s3 = gcps.select(gcps.scene == "S3")
        gcp_path = tmp_path / "gcps_all.gpkg"
        G.write_gpkg(s3 if len(s3) else gcps, gcp_path)
        fields = {"ties": LayerFile(str(path)), "gcps": LayerFile(str(gcp_path))}
    outputs = {k: str(tmp_path / v) for k, v in fields.pop("outputs", {}).items()}
    with pytest.raises(InputError, match=message) as refused:
        use_case.run(request(block, tmp_path / "out", outputs=outputs, **fields))
    assert refused.value.parameter == parameter
    assert not (tmp_path / "out").exists()
