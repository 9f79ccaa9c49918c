"""pushbroom:bundleadjust on a block of scenes with control lines (SCENES + LINES, issue 23;
Tommaselli & Marcato Junior 2012): a simulated TH-1 tri-stereo (pushbroom:simulateblock: nadir,
forward and backward scenes of one pass, each its own onboard errors, 600 x 600 px) with the
simulator's tie points and no GCP, and 8 straight ground lines whose image lines, projected
through each TRUE scene with 0.3 px noise (tests/support/control_lines.py block_lines), name their
scene in the field ``scene``. Each adjusted scene is checked against the simulation's true scene;
the line residuals carry their scene; a line layer without a scene field, a line naming a scene
not in the block, lines in a block with an RPC product and the one-scene line output are refused
naming the parameter."""
import json
from dataclasses import replace

import numpy as np
import pytest
from osgeo import ogr
from qgis.core import QgsProcessingException

import processing
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.observations.lines import write_gpkg
from tests.support.control_lines import block_lines
from tests.support.tristereo_block import ADJUST, NAMES, check_px, simulate_tristereo
from tests.support.processing import RecordingFeedback



@pytest.fixture(scope="module")
def block(provider, tmp_path_factory) -> dict:
    return simulate_tristereo(tmp_path_factory.mktemp("block"), n_gcps=4)


@pytest.fixture(scope="module")
def lines(block, tmp_path_factory) -> dict:
    """GeoPackages of the block's control lines: with the field scene ('good'), without it
    ('no_field'), one scene renamed date9 ('foreign')."""
    folder = tmp_path_factory.mktemp("lines")
    control, _ = block_lines({name: load_scene(path) for name, path in zip(NAMES, block["TRUE_SCENES"])})
    image = control.image
    out = {}
    for key, scene in (("good", image.scene), ("no_field", None),
                       ("foreign", np.where(image.scene == "bwd", "date9", image.scene))):
        out[key] = str(folder / f"{key}.gpkg")
        write_gpkg(out[key], control.ground, replace(image, scene=scene))
    out["count"] = int(image.col.size)
    return out


def params(block, folder, **kw) -> dict:
    return {"SCENES": list(block["SCENES"]), "TIE_POINTS": block["TIE_POINTS"], **ADJUST,
            "OUTPUT_FOLDER": str(folder), **kw}


def test_a_block_with_control_lines_meets_the_truth(block, lines, tmp_path):
    """No GCP: the simulator's 60 tie points and the control lines. Measured check RMSE through the
    onboard scenes nad 10.65, fwd 10.17, bwd 9.64 px; adjusted 0.20, 0.23, 0.24 px (what is left is
    mostly the simulated interior distortion, which a trajectory-only adjustment does not model);
    with the ties alone (the onboard sigmas holding the datum) 3.4, 6.5, 3.5 px. The lines'
    across-line misfit 38, 39, 37 m before, 1.5, 1.7, 1.4 m after (273 of 274 line points used);
    sigma0 0.75. The line residuals name each point's scene; the log and the report give each
    scene's lines."""
    log = RecordingFeedback()
    out = processing.run("pushbroom:bundleadjust", params(block, tmp_path / "out", LINES=lines["good"]), feedback=log)
    before, after = check_px(block, block["SCENES"]), check_px(block, out["ADJUSTED_SCENES"])
    for name in NAMES:
        assert before[name] > 5.0 and after[name] < 0.5, (name, before[name], after[name])
    report = json.loads((tmp_path / "out" / "block_report.json").read_text())
    assert "control lines" in report["datum"]
    page = (tmp_path / "out" / "block_report.html").read_text()
    assert "across-line RMS before m" in page and "line points used" in page
    for name in NAMES:
        entry = report["scenes"][name]["lines"]
        assert entry["lines"] == 8 and entry["across_rmse_before_m"] > 25.0 and entry["across_rmse_m"] < 2.5, entry
        assert any(line.startswith(f"scene {name}: ") and "8 control lines" in line for line in log.lines), log.lines
    ds = ogr.Open(str(tmp_path / "out" / "line_residuals.gpkg"))
    features = list(ds.GetLayer("line_points"))
    assert len(features) == lines["count"] and {f.GetField("scene") for f in features} == set(NAMES)
    assert ds.GetLayer("ground_lines").GetFeatureCount() == 8


@pytest.mark.parametrize("change, message", [
    (lambda x: {"LINES": x["no_field"]},
     r"^LINES: the layer image_lines of .*no_field.gpkg has no field 'scene'; in a block of 3 scenes \(nad, fwd, "
     r"bwd\) every image line names the scene it was measured in"),
    (lambda x: {"LINES": x["foreign"]},
     r"^LINES: lines: scene\(s\) date9 of line\(s\) L\d.* not in the block \(scenes: nad, fwd, bwd\)$"),
    (lambda x: {"LINES": x["good"], "OUTPUT_LINE_RESIDUALS": x["good"].replace("good", "res")},
     r"^OUTPUT_LINE_RESIDUALS: with SCENES the block's outputs go to OUTPUT_FOLDER \(it writes line_residuals.gpkg "
     r"with LINES there\)"),
])
def test_bad_block_lines_are_refused_naming_the_parameter(block, lines, tmp_path, change, message):
    with pytest.raises(QgsProcessingException, match=message):
        processing.run("pushbroom:bundleadjust", params(block, tmp_path / "out", **change(lines)))
    assert not (tmp_path / "out").exists()


def test_lines_in_a_block_with_an_rpc_product_are_refused(block, lines, shared_data, tmp_path):
    """Control lines need rigorous scene models: the block with an RPC product (the real Pleiades
    image over Giza, tests/data/pleiades_gizeh) and lines is refused naming the product."""
    scenes = [*block["SCENES"], str(shared_data / "pleiades_gizeh" / "img1_RPC.TXT")]
    with pytest.raises(QgsProcessingException, match=r"^LINES: lines: the block holds the RPC product\(s\) img1; "
                                                     "control lines need rigorous"):
        processing.run("pushbroom:bundleadjust", params(block, tmp_path / "out", SCENES=scenes, LINES=lines["good"]))
    assert not (tmp_path / "out").exists()
