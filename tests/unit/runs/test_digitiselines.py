"""The line dock's session without its widgets (core.runs.digitiselines), on the rendered block of
tests/support/gcpblock.py: a ground line through two GCPs' true ground positions predicted by the true
model passes through their true pixels; lines digitised, paired with the nearest ground line, refused
while unpaired, and saved naming their scene, never over a file the session reads."""
from pathlib import Path

import numpy as np
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.files import OutputError
from pushbroom_adjust.core.measure.snapping import SnapSettings
from pushbroom_adjust.core.measure.sources import ImageSource, open_image_source
from pushbroom_adjust.core.observations.lines import read_image_lines
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.runs.digitiselines import LineSession
from tests.support.gcpblock import gcp_block, true_ground, true_pixel  # noqa: F401 (the fixture)


def true_source(block) -> ImageSource:
    """The nad image with its true model (its scene file named as the onboard one)."""
    member = block["result"].members["nad"]
    return ImageSource(str(member["onboard_scene"]), block["true"]["nad"], 0, "NAD", Path(member["images"]["NAD"]),
                       Path(block["displays"]["nad"]))


def test_a_ground_line_predicted_by_the_true_model_passes_through_the_true_pixels(gcp_block):  # noqa: F811
    a, b = gcp_block["inside"][:2]
    session = LineSession()
    with pytest.raises(InputError, match="^No scene: open the image with its scene file"):
        session.predict(lambda: ([], []), Heights("z", "ellipsoid"), "")
    assert session.open(gcp_block["displays"]["nad"], true_source(gcp_block)).endswith(
        f"shown, camera NAD of {gcp_block['result'].members['nad']['onboard_scene']}")
    ground = np.array([true_ground(gcp_block, a), true_ground(gcp_block, b)])
    said = session.predict(lambda: (["L1"], [ground]), Heights("z", "ellipsoid"), "the lines' Z")
    assert said == "1 of 1 ground lines predicted into the image, heights from the lines' Z"
    assert [kind for _, kind in session.bands()] == ["predicted"]
    run = session.predicted[0].runs()[0]
    assert len(run) > 2  # densified: a straight ground segment is not straight in a pushbroom image
    assert np.hypot(*(run[0] - true_pixel(gcp_block, a, "nad"))) < 0.01
    assert np.hypot(*(run[-1] - true_pixel(gcp_block, b, "nad"))) < 0.01


def test_lines_are_paired_with_the_nearest_ground_line_and_saved_with_their_scene(gcp_block, tmp_path):  # noqa: F811
    session = LineSession()
    with pytest.raises(InputError, match="^Open the image first$"):
        session.snap(SnapSettings())
    display = gcp_block["displays"]["nad"]
    source = open_image_source(display, tmp_path / "cache")
    session.open(display, source)
    assert session.scene_words() == f"{source.scene_path} (NAD)" and session.raw_image == str(source.image)
    for col, row in ((10.0, 20.0), (30.0, 40.0)):
        session.editor.add_vertex(col, row)
    assert session.finish() == "Line 1 finished: press Pair, then click its ground line on the map"
    session.editor.add_vertex(50.0, 60.0)
    session.editor.add_vertex(70.0, 65.0)
    session.finish()
    parts = [np.array([[0.0, 0.0], [10.0, 0.0]]), np.array([[0.0, 5.0], [10.0, 5.0]])]
    assert session.pair(["A", "B"], parts, 4.0, 3.0) == "Line 2 paired with ground line B"   # 2 from B, 3 from A
    assert session.rows() == ["1: not paired (2 vertices)", "2: B (2 vertices)"]
    session.editor.add_vertex(90.0, 91.0)
    assert session.bands() == [([(10.0, 20.0), (30.0, 40.0)], "line"), ([(50.0, 60.0), (70.0, 65.0)], "selected"),
                               ([(90.0, 91.0)], "drawing")]
    assert session.selected_pixels() == [(50.0, 60.0), (70.0, 65.0)]
    session.undo()
    with pytest.raises(InputError, match="image line\\(s\\) 1 are not paired"):
        session.save(str(tmp_path / "lines.gpkg"), lambda paths: ["scene7"])
    assert not (tmp_path / "lines.gpkg").exists()
    session.editor.select(0)
    session.pair(["A", "B"], parts, 4.0, 1.0)
    for taken in (source.image, source.display, display):
        with pytest.raises(OutputError, match="is the file of NAD"):
            session.save(str(taken), lambda paths: ["scene7"])
    assert session.save(str(tmp_path / "lines.gpkg"), lambda paths: ["scene7"]) == \
        f"2 image lines saved to {tmp_path / 'lines.gpkg'}"
    back = read_image_lines(tmp_path / "lines.gpkg")
    assert back.line_id.tolist() == ["A", "B"] and back.scene.tolist() == ["scene7"] * 2
    np.testing.assert_allclose(np.c_[back.col, back.row], [[10, 20], [30, 40], [50, 60], [70, 65]])
    assert session.delete() == "Line deleted" and session.delete() == "Select a line in the list first"
    assert session.undo() == "Last line removed" and session.undo() == "Nothing to undo"
