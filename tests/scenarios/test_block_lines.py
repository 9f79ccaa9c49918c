"""Control lines in a block (issue 23; Tommaselli & Marcato Junior 2012): three independent
simulations of the TH-1 three-line preset cut to 500 x 500 px (seeds 1, 2, 3 as in
tests/unit/adjust/test_block.py: position bias 10 m and drift 0.02 m/s, attitude bias 2e-4 rad and
drift 5e-7 rad/s, about 110 m on the ground; epochs a week apart), adjusted together by
:func:`core.adjust.block.adjust_block` with control lines and no GCP.

Lines (tests/support/control_lines.py block_lines): 8 straight ground lines 2 km long in 8
directions at 300-900 m, exact; 12 points along each projected through every camera of every TRUE
scene that sees them plus 0.3 px noise: 39 image lines (8 lines x 3 cameras in each scene, less the
ends outside an image), 345 line points, each image line naming its scene. Tie points: the 32
ground points of an 8 x 8 lattice of S1's nadir image that two directions see, in every camera of
every true scene with 0.3 px (192 observations). Check figures: 49 true ground points projected
through the adjusted and the true scene of each camera (px RMS; 1 px is about 5 m)."""
from dataclasses import replace

import numpy as np
import pytest
from osgeo import ogr

from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.adjust.linepoints import ControlLines
from pushbroom_adjust.core.adjust.outputs import write_line_residuals
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.model.rpcscene import RpcCamera, RpcScene
from pushbroom_adjust.core.observations.lines import read_image_lines, write_gpkg
from tests.support.simulated_block import NOISE, SETTINGS, SimulatedBlock
from tests.support.control_lines import block_lines
from tests.support.rpcdata import pleiades_rpc

class LineBlock(SimulatedBlock):
    """The simulated block with control lines (tests/support/control_lines.py block_lines)."""

    def add_control(self, ref) -> None:
        self.lines, _ = block_lines(self.true, noise=NOISE)

    def lines_with(self, **image) -> ControlLines:
        """The lines with the image lines' fields replaced."""
        return ControlLines(self.lines.ground, replace(self.lines.image, **image))


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> LineBlock:
    return LineBlock(tmp_path_factory.mktemp("block_lines"))


@pytest.fixture(scope="module")
def with_ties(block):
    return adjust_block(block.onboard, None, block.ties, SETTINGS, lines=block.lines)


def test_lines_and_ties_hold_a_block_without_gcps(block, with_ties):
    """No GCP. Measured check errors (px RMS against the truth): onboard 22.5, 23.3, 24.2; lines and
    ties 0.09, 0.08, 0.13; the ties alone 8.3 in every scene (the datum from the onboard sigmas
    alone, about 40 m). The lines' across-line misfit (rays at the line's height) 87, 88, 93 m
    before, 1.4, 1.6, 1.5 m after (0.3 px noise at 5 m GSD); 344 of 345 line points used (one
    flagged in S1); sigma0 0.88."""
    ties_only = adjust_block(block.onboard, None, block.ties, SETTINGS)
    rep = with_ties.report
    for name in block.onboard:
        before, after = block.check_px(name, block.onboard[name]), block.check_px(name, with_ties.scenes[name])
        alone = block.check_px(name, ties_only.scenes[name])
        assert before > 20.0 and after < 0.25 and alone > 5.0, (name, before, after, alone)
        lines = rep["scenes"][name]["lines"]
        assert lines["lines"] == 8 and lines["points"] >= 110, (name, lines)
        assert lines["across_rmse_before_m"] > 80.0 and lines["across_rmse_m"] < 2.0, (name, lines)
    assert rep["block"]["lines"]["points"] + rep["block"]["lines"]["points_flagged"] == block.lines.image.col.size
    assert rep["adjustment"]["lines"]["lines"] == 8  # the engine's per-line figures, the lines shared by all scenes
    assert "control lines" in rep["datum"] and 0.7 < rep["block"]["sigma0"] < 1.3
    assert not rep["warnings"]
    # per line point: the scene it was measured in and the scene's own camera names
    points = with_ties.line_points
    assert sorted(set(points["scene"])) == ["S1", "S2", "S3"] and set(points["camera"]) == {"NAD", "FWD", "BWD"}


def test_lines_alone_hold_each_scene(block):
    """No GCP, no tie point: each scene held by the lines it sees. Measured check errors 0.10, 0.09,
    0.32 px (onboard 22.5, 23.3, 24.2); the datum sentence names the lines. A block of one scene
    takes image lines that name no scene."""
    out = adjust_block(block.onboard, None, None, SETTINGS, lines=block.lines)
    for name in block.onboard:
        assert block.check_px(name, out.scenes[name]) < 0.5, name
    assert out.report["datum"] == "datum held by the control lines (no tie points)"
    s1 = block.lines.image.scene == "S1"
    image = block.lines.image
    one = ControlLines(block.lines.ground, replace(
        image, line_id=image.line_id[s1], camera=image.camera[s1], scene=np.full(int(s1.sum()), ""),
        start=np.r_[0, np.cumsum(np.diff(image.start)[s1])], col=image.col[np.repeat(s1, np.diff(image.start))],
        row=image.row[np.repeat(s1, np.diff(image.start))],
        sigma_px=image.sigma_px[np.repeat(s1, np.diff(image.start))]))
    alone = adjust_block({"S1": block.onboard["S1"]}, None, None, SETTINGS, lines=one)
    assert block.check_px("S1", alone.scenes["S1"]) < 0.5
    assert set(alone.line_points["scene"]) == {"S1"}


def test_block_lines_are_written_with_their_scene(block, with_ties, tmp_path):
    """The image-line layer carries the field scene when lines name one (and not for one scene's
    lines); the line residuals of a block name each point's scene and its own camera."""
    write_gpkg(tmp_path / "lines.gpkg", block.lines.ground, block.lines.image)
    back = read_image_lines(tmp_path / "lines.gpkg")
    assert np.array_equal(back.scene, block.lines.image.scene) and np.array_equal(back.camera, block.lines.image.camera)
    assert read_image_lines(tmp_path / "lines.gpkg", scene_field=None).scene.tolist() == [""] * len(back)
    write_gpkg(tmp_path / "one.gpkg", image=replace(block.lines.image, scene=None))
    ds = ogr.Open(str(tmp_path / "one.gpkg"))  # kept: a layer dies with its data source
    defn = ds.GetLayer("image_lines").GetLayerDefn()
    names = [defn.GetFieldDefn(i).GetName() for i in range(defn.GetFieldCount())]
    assert "scene" not in names and read_image_lines(tmp_path / "one.gpkg").scene.tolist() == [""] * len(back)
    write_line_residuals(tmp_path / "res.gpkg", block.lines, with_ties.line_points, with_ties.report["adjustment"]
                         ["lines"])
    ds = ogr.Open(str(tmp_path / "res.gpkg"))
    features = list(ds.GetLayer("line_points"))
    assert len(features) == block.lines.image.col.size
    assert {(f.GetField("scene"), f.GetField("camera")) for f in features} == \
        {(s, c) for s in ("S1", "S2", "S3") for c in ("NAD", "FWD", "BWD")}


def test_bad_block_lines_are_named(block, shared_data):
    image = block.lines.image
    cases = [
        (dict(scene=np.where(image.scene == "S2", "", image.scene)),
         r"^lines: line\(s\) L0, .* have no scene; in a block of 3 scenes \(S1, S2, S3\)"),
        (dict(scene=np.where(image.scene == "S3", "S9", image.scene)),
         r"^lines: scene\(s\) S9 of line\(s\) L0, .* not in the block \(scenes: S1, S2, S3\)"),
        (dict(camera=np.where((image.scene == "S1") & (image.camera == "FWD"), "PAN", image.camera)),
         r"^lines: camera\(s\) PAN of line\(s\) L\d.* are not cameras of scene S1 \(cameras: NAD, FWD, BWD\)"),
    ]
    for change, message in cases:
        with pytest.raises(InputError, match=message) as err:
            adjust_block(block.onboard, None, block.ties, SETTINGS, lines=block.lines_with(**change))
        assert err.value.parameter == "lines"
    rpc = RpcScene(pleiades_rpc(shared_data), RpcCamera("PAN", 1000, 1000))
    with pytest.raises(InputError, match=r"^lines: the block holds the RPC product\(s\) P; control lines need "
                                         "rigorous") as err:
        adjust_block({**block.onboard, "P": rpc}, None, block.ties, SETTINGS, lines=block.lines)
    assert err.value.parameter == "lines"
    with pytest.raises(InputError, match=r"^lines: line\(s\) L0, .* are measured in the RPC product\(s\) P;"):
        adjust_block({**block.onboard, "P": rpc}, None, block.ties, SETTINGS,
                     lines=block.lines_with(scene=np.where(image.scene == "S3", "P", image.scene)))
