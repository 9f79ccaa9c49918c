"""core.runs.bundleadjust: the use case behind pushbroom:bundleadjust with one SCENE, on a TH-1 three-line
scene cut to 500 x 500 px (seed 4, its own trajectory errors, 0.3 px noise) with 30 GCPs (a quarter of them
check points) in a GeoPackage and the simulator's tie_points.csv: the adjusted scene written lies near the
truth, the files and figures returned are what the core's adjustment gives, and refusals name their
input and leave nothing behind."""
import json
from pathlib import Path

import numpy as np
import pytest

from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations import tiepoints
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.runs import bundleadjust as use_case
from pushbroom_adjust.core.runs.adjustinputs import AdjustRequest, LayerFile
from pushbroom_adjust.core.runs.base import FilesInUse
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.presets import PRESETS, cut_preset
from pushbroom_adjust.simulation.simulator import simulate

SETTINGS = AdjustmentSettings(position_order=1, attitude_order=1, position_sigma=20.0, attitude_sigma=2e-4)


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> dict:
    """The simulation, its GCPs as a GeoPackage (layer gcps) and as a table, its tie points' CSV."""
    folder = tmp_path_factory.mktemp("runs_adjust")
    sim = simulate(cut_preset(PRESETS["th1_tlc"], 500, 500), folder / "sim", seed=4,
                   gcp_settings=GcpSettings(n_gcps=30, n_tie_points=40, image_noise=0.3, check_fraction=0.25))
    table = G.read_csv(sim.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"), sigma_px=0.3, sigma_xy=0.5, sigma_z=0.5)
    gpkg = folder / "gcps.gpkg"
    G.write_gpkg(table, gpkg)
    return {"sim": sim, "gpkg": str(gpkg), "table": table, "ties": str(sim.tie_points)}


def request(scene, **fields) -> AdjustRequest:
    return AdjustRequest(**{"scene": str(scene["sim"].onboard_scene), "gcps": LayerFile(scene["gpkg"]),
                            "ties": LayerFile(scene["ties"]), "settings": SETTINGS, **fields})


def lattice_px(true, scene) -> float:
    """RMS (px) over the cameras of a 9 x 9 lattice's true ground (at 600 m) through ``scene``."""
    d = []
    for c, cam in enumerate(true.cameras):
        col, row = (a.ravel() for a in np.meshgrid(np.linspace(20, cam.cols - 20, 9),
                                                    np.linspace(20, cam.rows - 20, 9)))
        ground = true.image_to_ground(col, row, np.full(col.size, 600.0), c)
        col2, row2 = scene.ground_to_image(ground, c)
        d.append(np.hypot(col2 - col, row2 - row))
    return float(np.sqrt(np.mean(np.concatenate(d) ** 2)))


def test_the_adjusted_scene_written_is_the_core_s_and_near_the_truth(scene, tmp_path):
    outputs = {"OUTPUT_SCENE": tmp_path / "adj.json",
               "OUTPUT_REPORT": tmp_path / "report.html", "OUTPUT_GCPS": tmp_path / "gcps_out.gpkg",
               "OUTPUT_RESIDUALS": tmp_path / "vectors.gpkg", "OUTPUT_TIE_POINTS": tmp_path / "ties_out.gpkg"}
    result = use_case.run(request(scene, outputs={k: str(v) for k, v in outputs.items()}))
    assert result.files == {**{k: str(v) for k, v in outputs.items()}, "OUTPUT_RPC": None,
                            "OUTPUT_LINE_RESIDUALS": None, "OUTPUT_REPORT_JSON": str(tmp_path / "report.json")}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adj.json", "gcps_out.gpkg", "report.html", "report.json",
                                                         "ties_out.gpkg", "vectors.gpkg"]
    # the same solution as the core's adjustment of the same tables
    ties = tiepoints.check_against_scene(tiepoints.read_csv(scene["ties"]), load_scene(scene["sim"].onboard_scene))
    direct = adjust(load_scene(scene["sim"].onboard_scene), scene["table"], SETTINGS, ties=ties)
    report = result.figures["report"]
    assert report["sigma0"] == direct.report["sigma0"] and 0.7 < report["sigma0"] < 1.3
    assert json.loads((tmp_path / "report.json").read_text())["sigma0"] == pytest.approx(report["sigma0"])
    # the written scene against the truth: Measured, lattice RMS 19.9 px onboard, 0.21 px adjusted; sigma0 0.87
    true = load_scene(scene["sim"].true_scene)
    before, after = lattice_px(true, load_scene(scene["sim"].onboard_scene)), lattice_px(true, load_scene(outputs[
        "OUTPUT_SCENE"]))
    assert before > 15.0 and after < 0.4, (before, after)
    texts = [line.text for line in result.lines]
    n_ties = len(tiepoints.read_csv(scene["ties"]))
    assert f"{n_ties} tie observations from {scene['ties']}" in texts
    rows, control = len(scene["table"]), int((scene["table"].role == "control").sum())
    assert f"{rows} points from {scene['gpkg']}: {control} control, {rows - control} check" in texts
    # what the check of the tie points against the scene noticed, as a warning of the log
    assert any(line.warning and "seen in one camera only, kept in the layer" in line.text for line in result.lines)
    assert any(t.startswith("sigma0") for t in texts)


def test_without_outputs_asked_only_the_scene_is_written(scene, tmp_path):
    out = tmp_path / "only.json"
    result = use_case.run(request(scene, ties=None, outputs={"OUTPUT_SCENE": str(out)}))
    assert result.files["OUTPUT_SCENE"] == str(out) and result.files["OUTPUT_REPORT_JSON"] is None
    assert [p.name for p in tmp_path.iterdir()] == ["only.json"]
    assert "adjustment" in load_scene(out).info and result.figures["report"].tie_points is None


@pytest.mark.parametrize("fields, parameter, message", [
    ({"outputs": {"OUTPUT_RPC": "x_RPC.TXT"}}, "OUTPUT_RPC", r"^only for a SCENE given by its RPC"),
    ({"folder": "block"}, "OUTPUT_FOLDER", r"^for a block of scenes \(SCENES\) only"),
    ({"write_rpcs": True}, "WRITE_RPCS", r"^for a block of scenes \(SCENES\) only"),
    ({"scene_sigmas": ("S", "1", "", "")}, "settings.scene_sigmas", r"^SCENE_SIGMAS: per-scene sigmas are for a block"),
    ({"outputs": {"OUTPUT_REPORT": "report.pdf"}}, "OUTPUT_REPORT", r"^expected a \.html file"),
    ({"ties": None, "outputs": {"OUTPUT_TIE_POINTS": "t.gpkg"}}, "OUTPUT_TIE_POINTS", r"need TIE_POINTS"),
    ({"outputs": {"OUTPUT_LINE_RESIDUALS": "l.gpkg"}}, "OUTPUT_LINE_RESIDUALS", r"^no LINES given"),
    ({"gcps": None, "ties": None}, "gcps", r"^no GCP layer given"),
    ({"gcps": LayerFile("gcps.csv")}, "gcps", r"is not a GeoPackage"),
    ({"settings": AdjustmentSettings(interior="PAN.*")}, "settings.interior",
     r"This scene has camera NAD with chips NAD-1; camera FWD with chips FWD-1; camera BWD"),
])
def test_refusals_name_their_input_and_leave_nothing(scene, tmp_path, fields, parameter, message):
    outputs = {"OUTPUT_SCENE": str(tmp_path / "adj.json"),
               **{k: str(tmp_path / v) for k, v in fields.pop("outputs", {}).items()}}
    with pytest.raises(InputError, match=message) as refused:
        use_case.run(request(scene, outputs=outputs, **fields))
    assert refused.value.parameter == parameter
    assert list(tmp_path.iterdir()) == []


def test_an_output_may_not_replace_an_input(scene, tmp_path):
    with pytest.raises(InputError, match=r"OUTPUT_SCENE: .* is the file of GCPS"):
        use_case.run(request(scene, outputs={"OUTPUT_SCENE": scene["gpkg"].replace(".gpkg", ".json")},
                             files=FilesInUse({"GCPS": [scene["gpkg"].replace(".gpkg", ".json")]})))
    assert not Path(scene["gpkg"].replace(".gpkg", ".json")).exists()
