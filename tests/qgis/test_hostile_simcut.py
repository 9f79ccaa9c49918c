"""Hostile inputs of simulatescene's IMAGE_SIZE (a preset's cameras cut to a small block): a
multi-chip camera, a cut below the smallest or beyond the full camera — each refused with the
parameter named and nothing written; 0 is the full preset."""
import pytest

import processing

from tests.support.hostile import assert_refused

CASES = [
    ("cbers-three-chips", "cbers02b_hrc", 2000, ("a cut needs cameras of one detector line",
                                                 "cbers02b_hrc camera HRC has 3 CCD chips")),
    ("below-the-smallest", "th1_tlc", 100, ("must be 500 to 12000 detectors", "got 100 x 100")),
    ("beyond-the-full-camera", "th1_tlc", 20000, ("must be 500 to 12000 detectors", "got 20000 x 20000")),
]


@pytest.mark.parametrize("case, preset, size, texts", CASES, ids=[c[0] for c in CASES])
def test_a_bad_cut_is_refused(provider, tmp_path, case, preset, size, texts):
    folder = tmp_path / "sim"
    assert_refused("pushbroom:simulatescene", {"PRESET": preset, "N_GCPS": 5, "IMAGE_SIZE": size,
                                               "OUTPUT_FOLDER": str(folder)}, "IMAGE_SIZE", *texts, watch=[tmp_path])
    assert not folder.exists()


def test_a_cut_block_has_the_cut_cameras(provider, tmp_path):
    """A legitimate cut: every camera 600 px wide, the nadir strip 600 lines long (the tilted
    cameras' trimmed to the lines that see the block), the preset's name with the cut recorded
    in simulation.json."""
    import json

    from pushbroom_adjust.core.formats import load_scene
    out = processing.run("pushbroom:simulatescene", {"PRESET": "th1_tlc", "N_GCPS": 5, "IMAGE_SIZE": 600,
                                                     "OUTPUT_FOLDER": str(tmp_path / "sim")})
    scene = load_scene(out["ONBOARD_SCENE"])
    assert [(c.name, c.cols) for c in scene.cameras] == [("NAD", 600), ("FWD", 600), ("BWD", 600)]
    assert scene.cameras[0].rows == 600 and all(400 < c.rows <= 600 for c in scene.cameras[1:])
    manifest = json.loads((tmp_path / "sim" / "simulation.json").read_text())
    assert "th1_tlc_600x600" in json.dumps(manifest)
    assert out["IMAGES"] == []
