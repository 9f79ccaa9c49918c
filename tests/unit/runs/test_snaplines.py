"""core.runs.snaplines: clicks 2 px off a rendered road (tests/support/snapping.py) snapped to its
centre line within 0.3 px RMS across, the refined count per line written and said."""
import numpy as np
import pytest
from osgeo import ogr

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.measure.snapping import SnapSettings
from pushbroom_adjust.core.observations.lines import read_image_lines, write_gpkg
from pushbroom_adjust.core.runs import snaplines as use_case
from tests.support.snapping import across_error, clicks_along


def test_clicks_snap_to_the_road_s_centre(rendered, tmp_path):
    path, scene, truth = rendered
    clicks = clicks_along(truth, 40.0, 2.0, np.random.default_rng(1), scene.cameras[0].cols)
    write_gpkg(tmp_path / "clicks.gpkg", image=clicks)
    out = str(tmp_path / "snapped.gpkg")
    result = use_case.run(use_case.SnapRequest(out, str(path), (str(tmp_path / "clicks.gpkg"), None),
                                               SnapSettings(mode="centre", width=3.0, search=10.0)))
    snapped = read_image_lines(out)
    refined = snapped.sigma_px != 2.0
    after = across_error(snapped, truth)
    assert np.sqrt(np.mean(after[refined] ** 2)) <= 0.3
    assert result.figures == {"refined": int(refined.sum()), "vertices": len(snapped.col)}
    assert result.figures["refined"] >= 0.95 * len(snapped.col)
    assert result.lines[0].text.startswith(f"{refined.sum()} of {len(snapped.col)} vertices refined (centre;")
    ds = ogr.Open(out)  # held: its layer dies with it
    assert sum(f.GetField("refined") for f in ds.GetLayer("image_lines")) == refined.sum()


def test_out_of_range_settings_are_refused_before_any_output(rendered, tmp_path):
    path, scene, truth = rendered
    write_gpkg(tmp_path / "clicks.gpkg", image=clicks_along(truth, 40.0, 2.0, np.random.default_rng(1),
                                                            scene.cameras[0].cols))
    lines = (str(tmp_path / "clicks.gpkg"), None)
    with pytest.raises(InputError) as refused:
        use_case.run(use_case.SnapRequest(str(tmp_path / "o.gpkg"), str(path), lines, SnapSettings(width=-1.0)))
    assert refused.value.parameter == use_case.SETTINGS
    assert not (tmp_path / "o.gpkg").exists()
