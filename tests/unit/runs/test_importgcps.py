"""core.runs.importgcps: the simulator's noise-free GCPs imported against the true scene have no
a-priori residual, against the onboard scene the residual of its known errors; the block mode checks
each row against the scene it names; refusals name their input."""
import csv

import numpy as np
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.observations import gcps
from pushbroom_adjust.core.runs import importgcps as use_case
from pushbroom_adjust.core.runs.layers import PointHeights
from tests.unit.runs.conftest import N_GCPS


def _rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_noise_free_gcps_fit_the_true_scene_and_not_the_onboard_one(th1, tmp_path):
    rows = _rows(th1["GCPS"])
    results = {}
    for kind in ("TRUE_SCENE", "ONBOARD_SCENE"):
        out = str(tmp_path / f"{kind}.gpkg")
        results[kind] = use_case.run(use_case.ImportGcpsRequest(
            out, th1[kind], file=th1["GCPS"], crs="EPSG:4326", heights=PointHeights("z", "ellipsoid"),
            mapping=gcps.CsvMapping(z="h", scene="")))
        assert results[kind].files == {"OUTPUT": out}
    true, onboard = results["TRUE_SCENE"].figures, results["ONBOARD_SCENE"].figures
    assert true["points"] == onboard["points"] == len(rows) >= N_GCPS
    assert true["check"] == 0 and true["outside"] == 0
    assert true["max_px"] < 1e-3 and onboard["median_px"] > 1.0
    table = gcps.read_gpkg(str(tmp_path / "TRUE_SCENE.gpkg"))
    assert len(table) == len(rows) and set(table.camera) == {r["camera"] for r in rows}
    lines = [line.text for line in results["TRUE_SCENE"].lines]
    assert lines[-2] == f"{len(rows)} points: {len(rows)} control, 0 check, 0 outside the image"


def test_a_block_checks_each_row_against_the_scene_it_names(th1, tmp_path):
    csv_path = tmp_path / "gcps.csv"
    rows = _rows(th1["GCPS"])
    with open(csv_path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=[*rows[0], "block"])
        writer.writeheader()
        for k, row in enumerate(rows):  # every second row measured in the onboard scene's "product"
            writer.writerow({**row, "block": "sim_true" if k % 2 else "sim_onboard"})
    folder = tmp_path / "block"
    files = {}
    for name, kind in (("sim_true", "TRUE_SCENE"), ("sim_onboard", "ONBOARD_SCENE")):
        files[name] = folder / f"{name}.json"
        files[name].parent.mkdir(exist_ok=True)
        files[name].write_text(open(th1[kind]).read())
    result = use_case.run(use_case.ImportGcpsRequest(
        str(tmp_path / "block.gpkg"), scenes=tuple(map(str, files.values())), file=str(csv_path), crs="EPSG:4326",
        heights=PointHeights("z", "ellipsoid"), mapping=gcps.CsvMapping(z="h", scene="block"), check_fraction=0.2))
    table = gcps.read_gpkg(str(tmp_path / "block.gpkg"))
    in_true = table.scene == "sim_true"
    assert in_true.sum() == len(rows) // 2 and np.nanmax(table.residuals.px[in_true]) < 1e-3
    assert np.nanmedian(table.residuals.px[~in_true]) > 1.0
    assert result.figures["check"] == round(0.2 * len(rows))


def test_refusals_name_their_input(th1, tmp_path):
    request = dict(file=th1["GCPS"], crs="EPSG:4326", mapping=gcps.CsvMapping(z="h", scene=""))
    with pytest.raises(InputError, match="GeoPackage") as refused:
        use_case.run(use_case.ImportGcpsRequest(str(tmp_path / "x.shp"), th1["TRUE_SCENE"], **request))
    assert refused.value.parameter == ""
    with pytest.raises(InputError, match="does not say what the Z values are measured from"):
        use_case.run(use_case.ImportGcpsRequest(str(tmp_path / "x.gpkg"), th1["TRUE_SCENE"], **request))
    with pytest.raises(InputError, match="no such file") as refused:
        use_case.run(use_case.ImportGcpsRequest(str(tmp_path / "x.gpkg"), str(tmp_path / "none.json"), **request))
    assert refused.value.parameter == "scene"
    assert not (tmp_path / "x.gpkg").exists()
