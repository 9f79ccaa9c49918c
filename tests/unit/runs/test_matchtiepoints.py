"""core.runs.matchtiepoints: tie points matched between the three rendered cameras of a TH-1 scene
intersect through the true scene within a fraction of a pixel; a block of scenes whose cameras are
of one image's size (FWD, BWD) is refused, naming IMAGES."""
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.runs import matchtiepoints as use_case
from pushbroom_adjust.core.runs.base import Terrain

MATCHING = {"spacing": 60.0, "search": 300.0}


def test_ties_between_the_cameras_intersect_through_the_true_scene(th1, tmp_path):
    out = str(tmp_path / "t.gpkg")
    result = use_case.run(use_case.MatchTiesRequest(out, tuple(th1["IMAGES"]), th1["TRUE_SCENE"],
                                                    terrain=Terrain(th1["DEM"], "geoid"), matching=MATCHING))
    s = result.figures
    assert result.files == {"OUTPUT": out}
    assert s["points"] >= 20 and set(s["cameras"]) == {"NAD", "FWD", "BWD"} and s["rms_px"] < 0.3
    texts = [line.text for line in result.lines]
    assert [t for t in texts if t.startswith("camera ")] == [f"camera {c}: {p}" for c, p in
                                                            zip(("NAD", "FWD", "BWD"), th1["IMAGES"])]
    assert any(t.startswith("NAD-FWD: matched ") for t in texts) and any(t.startswith("NAD-BWD: matched ")
                                                                         for t in texts)


def test_refusals(th1, tmp_path):
    with pytest.raises(InputError, match="2 raw image") as refused:
        use_case.run(use_case.MatchTiesRequest(str(tmp_path / "t.gpkg"), tuple(th1["IMAGES"][:2]), th1["TRUE_SCENE"]))
    assert refused.value.parameter == use_case.IMAGES
    copies = []
    for name in ("a", "b"):
        copies.append(tmp_path / f"{name}.json")
        copies[-1].write_text(open(th1["TRUE_SCENE"]).read())
    with pytest.raises(InputError, match="has the size of 2 cameras of scene a") as refused:  # FWD and BWD
        use_case.run(use_case.MatchTiesRequest(str(tmp_path / "t.gpkg"), tuple(th1["IMAGES"][1:]),
                                               scenes=tuple(map(str, copies))))
    assert refused.value.parameter == use_case.IMAGES
    with pytest.raises(InputError, match="1 scene given") as refused:
        use_case.run(use_case.MatchTiesRequest(str(tmp_path / "t.gpkg"), (th1["IMAGE"],), scenes=(str(copies[0]),)))
    assert refused.value.parameter == "scenes"
    assert not (tmp_path / "t.gpkg").exists()
