"""core.files: outputs checked before any work, written completely or not at all under private
temporary names, modes from the umask, concurrent writers safe, a full disk an error."""
import gc
import os
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from osgeo import ogr, osr

from pushbroom_adjust.core import files as F
from pushbroom_adjust.core.files import Output, OutputError, atomic_output, atomic_outputs, check_outputs, file_key, write_text
from pushbroom_adjust.core.vector_io import feature_count, write_layer
from tests.support.mounts import read_only_folder, tiny_disk

REPO = Path(__file__).resolve().parents[3]


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.fixture
def umask():
    """Set a umask for the test, restore the previous one after."""
    previous = os.umask(0o022)
    yield os.umask
    os.umask(previous)


@pytest.fixture
def tiny(tmp_path):
    """A 256 KiB disk (tests/mounts.py)."""
    with tiny_disk(tmp_path / "tiny") as folder:
        yield folder


@pytest.fixture
def read_only(tmp_path):
    """A read-only folder holding old.json (tests/mounts.py)."""
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro" / "old.json").write_text("old")
    with read_only_folder(tmp_path / "ro") as folder:
        yield folder


def _gpkg(path, n: int = 3, files=None) -> None:
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    write_layer(path, "pts", srs, ogr.wkbPoint, {"v": np.arange(n, dtype=float)},
                [f"POINT ({i} 1)" for i in range(n)], files=files)


# --- writing --------------------------------------------------------------------------------------
def test_a_written_file_replaces_the_old_one_and_leaves_nothing_else(tmp_path):
    (tmp_path / "a.json").write_text("old")
    write_text(tmp_path / "a.json", "new")
    assert (tmp_path / "a.json").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_a_failure_keeps_the_old_file_and_removes_what_the_run_wrote(tmp_path):
    (tmp_path / "a.json").write_text("old")
    with pytest.raises(ZeroDivisionError):
        with atomic_output(tmp_path / "a.json") as tmp:
            tmp.write_text("half")
            (tmp.parent / "a.json-journal").write_text("a driver's side file")
            1 / 0
    assert (tmp_path / "a.json").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_a_set_of_files_is_committed_together_or_not_at_all(tmp_path):
    for name in ("s.json", "r.html"):
        (tmp_path / name).write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_outputs() as files:
            write_text(tmp_path / "s.json", "new", files)
            write_text(tmp_path / "r.html", "new", files)
            raise RuntimeError("the third output failed")
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == {"s.json": "old", "r.html": "old"}
    with atomic_outputs() as files:
        write_text(tmp_path / "s.json", "new", files)
        write_text(tmp_path / "r.html", "new", files)
        assert (tmp_path / "s.json").read_text() == "old"  # nothing replaced before the end
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == {"s.json": "new", "r.html": "new"}


@pytest.mark.parametrize("name", ["x.json.part", "x.part.gpkg", "x.gpkg.part", ".x.json.part", "x.part.tif"])
def test_files_at_the_old_fixed_temporary_names_are_left_alone(tmp_path, name):
    (tmp_path / name).write_text("a user's file")
    write_text(tmp_path / "x.json", "new")
    _gpkg(tmp_path / "x.gpkg")
    assert (tmp_path / name).read_text() == "a user's file"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, "x.json", "x.gpkg"])


def test_a_symlink_at_the_temporary_name_is_not_followed(tmp_path, monkeypatch):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    trap = tmp_path / ".out.json.trapname.part"
    trap.symlink_to(victim)
    names = iter(["trapname", "freename"])
    monkeypatch.setattr(tempfile, "_get_candidate_names", lambda: names)
    write_text(tmp_path / "out.json", "new")
    assert victim.read_text() == "precious" and trap.is_symlink()
    assert (tmp_path / "out.json").read_text() == "new"


def test_a_destination_symlink_is_written_through_and_stays(tmp_path):
    target = tmp_path / "data" / "scene.json"
    target.parent.mkdir()
    target.write_text("old")
    (tmp_path / "link.json").symlink_to(target)
    write_text(tmp_path / "link.json", "new")
    assert (tmp_path / "link.json").is_symlink() and target.read_text() == "new"


@pytest.mark.parametrize("mask", [0o022, 0o027, 0o002])
def test_modes_follow_the_umask(tmp_path, umask, mask):
    umask(mask)
    write_text(tmp_path / "a.json", "x")
    _gpkg(tmp_path / "b.gpkg")
    expected = 0o666 & ~mask
    assert _mode(tmp_path / "a.json") == expected and _mode(tmp_path / "b.gpkg") == expected


def test_concurrent_writers_of_the_same_outputs_leave_one_whole_file(tmp_path):
    """8 processes write the same two files 15 times each, with contents of different sizes:
    no writer fails, and each file ends as one writer's whole content."""
    script = ("import sys; from core.files import atomic_outputs, write_text\n"
              "k = int(sys.argv[1]); out = sys.argv[2]\n"
              "for i in range(15):\n"
              "    with atomic_outputs() as files:\n"
              "        write_text(out + '/a.txt', str(k) * (1000 * (k + 1)), files)\n"
              "        write_text(out + '/b.txt', str(k) * (1000 * (k + 1)), files)\n")
    procs = [subprocess.Popen([sys.executable, "-c", script, str(k), str(tmp_path)], cwd=REPO,
                              stderr=subprocess.PIPE, text=True) for k in range(8)]
    for p in procs:
        assert p.wait(timeout=120) == 0, p.stderr.read()
    for name in ("a.txt", "b.txt"):
        text = (tmp_path / name).read_text()
        assert len(set(text)) == 1 and len(text) == 1000 * (int(text[0]) + 1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]


def test_a_full_disk_is_an_error_and_keeps_the_old_file(tiny, monkeypatch):
    """Named as a full disk; GDAL's errors on closing the GeoPackage are caught, none reaches Python's
    'Exception ignored' hook (stderr)."""
    ignored = []
    monkeypatch.setattr(sys, "unraisablehook", ignored.append)
    (tiny / "a.json").write_text("old")
    with pytest.raises(OutputError, match="a.json: no space left on the device holding"):
        write_text(tiny / "a.json", "x" * 1_000_000)
    with pytest.raises(OutputError, match="b.gpkg: no space left on the device holding"):
        _gpkg(tiny / "b.gpkg", n=20000)
    gc.collect()
    assert [str(u.exc_value) for u in ignored] == []
    assert [p.name for p in tiny.iterdir()] == ["a.json"] and (tiny / "a.json").read_text() == "old"


def test_a_read_only_folder_is_refused_before_writing(read_only):
    with pytest.raises(OutputError, match="is not writable"):
        write_text(read_only / "new.json", "x")
    assert [p.name for p in read_only.iterdir()] == ["old.json"]


def test_a_geopackage_holds_every_feature_written(tmp_path):
    _gpkg(tmp_path / "p.gpkg", n=1234)
    assert feature_count(tmp_path / "p.gpkg") == 1234 and feature_count(tmp_path / "none.gpkg") is None


# --- checks before any work ---------------------------------------------------------------------
def test_the_same_file_by_another_spelling_is_the_same_key(tmp_path, monkeypatch):
    (tmp_path / "d").mkdir()
    f = tmp_path / "d" / "a.tif"
    f.write_text("x")
    (tmp_path / "link.tif").symlink_to(f)
    os.link(f, tmp_path / "hard.tif")
    monkeypatch.chdir(tmp_path)
    same = [f, tmp_path / "link.tif", tmp_path / "hard.tif", Path("d/a.tif"), tmp_path / "d" / ".." / "d" / "a.tif"]
    assert len({file_key(p) for p in same}) == 1
    assert file_key(tmp_path / "d" / "b.tif") == file_key(Path("d/./b.tif")) != file_key(tmp_path / "d" / "B.tif")
    monkeypatch.setattr(F, "_case_insensitive", lambda folder: True)  # as on a FAT or macOS volume
    assert file_key(tmp_path / "d" / "b.tif") == file_key(tmp_path / "d" / "B.TIF")


def test_this_file_system_is_found_case_sensitive(tmp_path):
    assert not F._case_insensitive(tmp_path)


@pytest.mark.parametrize("outputs, message", [
    ({"OUTPUT": ["{d}/in.tif"]}, "OUTPUT: {d}/in.tif is the file of INPUT"),
    ({"OUTPUT": ["{d}/link.tif"]}, "OUTPUT: {d}/link.tif is the file of INPUT"),
    ({"OUTPUT": ["{d}/dem.tif"]}, "OUTPUT: {d}/dem.tif is the file of DEM"),
    ({"A": ["{d}/x.json"], "B": ["{d}/x.json"]}, "B: {d}/x.json is the file of A"),
    ({"OUTPUT_SCENE": ["{d}/r.json"], "OUTPUT_REPORT": ["{d}/r.html", Output(Path("{d}/r.json"), "its JSON report")]},
     "OUTPUT_REPORT: its JSON report {d}/r.json is the file of OUTPUT_SCENE"),
    ({"OUTPUT": ["{d}/o_RPC.TXT", Output(Path("{d}/o.vrt"), "its VRT")]}, "OUTPUT: its VRT {d}/o.vrt is the file of IMAGE"),
    ({"A": ["{d}/g.gpkg"], "B": ["{d}/g.gpkg-wal"]}, "B: {d}/g.gpkg-wal is its side file g.gpkg-wal of A"),
])
def test_an_output_over_an_input_or_another_output_is_refused_naming_both(tmp_path, outputs, message):
    d = str(tmp_path)
    for name in ("in.tif", "dem.tif", "o.vrt"):
        (tmp_path / name).write_text("input")
    (tmp_path / "link.tif").symlink_to(tmp_path / "in.tif")
    inputs = {"INPUT": [f"{d}/in.tif"], "DEM": [f"{d}/dem.tif"], "IMAGE": [f"{d}/o.vrt"], "SCENE": [""]}
    outputs = {k: [Output(Path(str(f.path).format(d=d)), f.label) if isinstance(f, Output) else f.format(d=d)
                   for f in v] for k, v in outputs.items()}
    with pytest.raises(OutputError) as info:
        check_outputs(inputs, outputs)
    assert message.format(d=d) in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.tif", "in.tif", "link.tif", "o.vrt"]


@pytest.mark.parametrize("make, message", [
    (lambda d: d / "missing" / "o.tif", "folder {d}/missing does not exist"),
    (lambda d: d, "it is a folder"),
    (lambda d: Path("/dev/null"), "it is not a regular file"),
    (lambda d: (d / "busy.gpkg-wal").write_text("") or d / "busy.gpkg", "it is open in another program"),
])
def test_a_destination_that_cannot_be_written_is_refused_naming_the_parameter(tmp_path, make, message):
    with pytest.raises(OutputError) as info:
        check_outputs({}, {"OUTPUT": [make(tmp_path)]})
    assert str(info.value).startswith("OUTPUT: cannot write") and message.format(d=tmp_path) in str(info.value)


def test_distinct_outputs_and_optional_ones_not_asked_for_pass(tmp_path):
    (tmp_path / "in.tif").write_text("x")
    check_outputs({"INPUT": [str(tmp_path / "in.tif")]},
                  {"OUTPUT": [str(tmp_path / "o.tif"), Output(None, "its report")], "OPTIONAL": [""]})


def test_closing_errors_of_overlapping_threads_stay_in_their_blocks(monkeypatch):
    """closing_errors swaps the process-wide unraisable hook: blocks of two threads overlapping in any
    order each keep their own thread's error, an error of a thread outside any block goes to the hook
    they replaced, and that hook is back once the last block ends (an unraisable error is raised here
    as GDAL's is: by a destructor that fails)."""
    import threading

    class FailsOnClose:
        def __init__(self, text):
            self.text = text

        def __del__(self):
            raise RuntimeError(self.text)

    outer = []
    monkeypatch.setattr(sys, "unraisablehook", outer.append)
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    found = {}

    def block(name, entered, wait_for, then=None):
        with F.closing_errors() as closing:
            entered.set()
            wait_for.wait(5)
            obj = FailsOnClose(f"closing {name}")
            obj = None  # noqa: F841 (the destructor fails here)
        found[name] = closing.message
        if then:
            then.set()

    a = threading.Thread(target=block, args=("a", a_in, b_in, a_out))
    b = threading.Thread(target=block, args=("b", b_in, a_out))
    a.start()
    a_in.wait(5)
    b.start()  # b enters after a and leaves after it
    for t in (a, b):
        t.join(5)
    stray = FailsOnClose("outside any block")
    stray = None  # noqa: F841
    assert found == {"a": "closing a", "b": "closing b"}
    assert sys.unraisablehook == outer.append and [str(u.exc_value) for u in outer] == ["outside any block"]


def test_messages_name_the_destination_not_the_temporary_file(tmp_path):
    files = F.OutputSet()
    tmp = files.path(tmp_path / "o.tif")
    second = files.path(tmp_path / "p.json")  # the same private folder, named after the first file
    try:
        assert F.destination_of(tmp) == tmp_path / "o.tif" and F.destination_of(second) == tmp_path / "p.json"
        assert F.destination_of(tmp_path / "o.tif") == tmp_path / "o.tif"
        closing = F.ClosingErrors("TIFFRewriteDirectory:Error fetching directory count")
        with pytest.raises(OutputError, match=rf"^cannot write {tmp_path / 'o.tif'}: TIFFRewrite"):
            F.check_closed(tmp, closing)
    finally:
        files.discard()
