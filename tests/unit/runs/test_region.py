"""core.runs.region on the real products of tests/data: a folder of vendor RPC products (each image beside
its _RPC.TXT counted once, the .geom files and a CSV not looked at), a folder tree of several product kinds, a
list file, and the images found beside RPC products."""
import shutil
from pathlib import Path

import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.runs.region import block_images, expand_scenes
from pushbroom_adjust.core.runs.scenes import block_from

DATA = Path(__file__).resolve().parents[2] / "data"


def test_a_folder_of_rpc_products_gives_each_once():
    files, lines = expand_scenes([str(DATA / "pleiades_gizeh")])
    assert files == (str(DATA / "pleiades_gizeh" / "img1_RPC.TXT"), str(DATA / "pleiades_gizeh" / "img2_RPC.TXT"))
    assert lines[0].text == f"SCENES folder {DATA / 'pleiades_gizeh'}: 2 product(s)"   # .geom, .csv not looked at
    block, _ = block_from([str(DATA / "pleiades_gizeh")])
    assert list(block.files) == ["img1", "img2"]
    assert block_images((), block) == (str(DATA / "pleiades_gizeh" / "img1.tif"),
                                       str(DATA / "pleiades_gizeh" / "img2.tif"))


def test_a_folder_tree_of_several_kinds_and_a_list(tmp_path):
    """Subfolders in name order: RPC products, Maxar XML, a Pleiades DIMAP document (the rasters beside it
    and the DEM without RPC metadata skipped, and named in the log)."""
    region = tmp_path / "region"
    shutil.copytree(DATA / "pleiades_ventoux", region / "a_ventoux")
    shutil.copytree(DATA / "worldview1", region / "b_wv1")
    (region / "b_wv1" / "LICENSE").unlink()
    shutil.copytree(DATA / "pleiades", region / "c_pleiades")
    files, lines = expand_scenes([str(region)])
    assert [Path(f).relative_to(region).as_posix() for f in files] == [
        "a_ventoux/left_image_RPC.TXT", "a_ventoux/right_image_RPC.TXT",
        "b_wv1/" + next(p.name for p in (DATA / "worldview1").glob("*.xml")),
        "c_pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"]
    assert lines[0].text == (f"SCENES folder {region}: 4 product(s); 3 file(s) skipped, not a product the plugin "
                             "reads: srtm_big_hole.tif, GRID_P1BP--2018122638935449CP.tif, "
                             "MNT_P1BP--2018122638935449CP.tif")
    listed = tmp_path / "region.lst"
    listed.write_text("# two of them\nregion/a_ventoux/right_image_RPC.TXT\n\n" + files[0] + "\n")
    assert expand_scenes([str(listed)])[0] == (str(tmp_path / "region/a_ventoux/right_image_RPC.TXT"), files[0])


def test_refusals(tmp_path):
    with pytest.raises(InputError, match=rf"^{tmp_path / 'nothing'}: no such file or folder") as refused:
        expand_scenes([str(tmp_path / "nothing")])
    assert refused.value.parameter == "scenes"
    listed = tmp_path / "products.txt"
    listed.write_text(f"{DATA / 'pleiades_gizeh' / 'img1_RPC.TXT'}\n{DATA / 'pleiades_gizeh'}\n")
    with pytest.raises(InputError, match=rf"^{listed}, line 2: '.*pleiades_gizeh' is a folder \(list product files\)"):
        expand_scenes([str(listed)])
    listed.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(InputError, match=rf"^{listed}: not a readable text list of products"):
        expand_scenes([str(listed)])
    listed.write_text("# nothing\n\n")
    with pytest.raises(InputError, match=rf"^{listed}: the list names no product"):
        expand_scenes([str(listed)])
