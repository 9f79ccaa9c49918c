"""Harness of the hostile-input suite (tests/qgis/test_hostile_*.py).

A run with bad input must stop with a QgsProcessingException whose message names the parameter
(or file, field) at fault — never another exception (a traceback for the user), never exit 0 —
and must leave the files it was given, and the folders it was to write to, exactly as they were:
no input modified, no partial output, no temporary file left behind.

Each case names what it watches; ``snapshot`` records size, mtime and a hash of every file there.
"""
from __future__ import annotations

import gc
import hashlib
import os
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import pytest
from osgeo import gdal
from qgis.core import QgsProcessingException, QgsProcessingFeedback

import processing


def snapshot(*paths) -> dict:
    """{path: (size, mtime_ns, mode, sha256)} of every file at or under ``paths`` (missing ones skipped)."""
    state = {}
    for p in map(Path, paths):
        files = [p] if p.is_file() else sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else []
        for f in files:
            st = f.stat()
            state[str(f)] = (st.st_size, st.st_mtime_ns, st.st_mode, hashlib.sha256(f.read_bytes()).hexdigest())
    return state


def assert_unchanged(before: dict, watch) -> None:
    after = snapshot(*watch)
    added = sorted(set(after) - set(before))
    removed = sorted(set(before) - set(after))
    changed = sorted(k for k in set(before) & set(after) if before[k] != after[k])
    assert not (added or removed or changed), f"files added {added}, removed {removed}, changed {changed}"


STDERR_TRACEBACKS = ("Traceback", "Exception ignored")
"""What a Python error the user should never see leaves on stderr: a traceback, or an error Python could
not raise (e.g. GDAL's on closing a file in a destructor: 'Exception ignored in: delete_Dataset')."""


def assert_clean_stderr(text: str) -> None:
    """No Python traceback of any kind in ``text`` (stderr, or stdout + stderr of a run)."""
    for mark in STDERR_TRACEBACKS:
        assert mark not in text, f"{mark!r} on stderr: {text}"


@contextmanager
def no_unraisable():
    """A block during which no error may reach Python's unraisable hook: an error raised where Python
    cannot raise it (a destructor: GDAL's on closing a file), printed as 'Exception ignored' on stderr
    outside pytest, which turns it into a mere warning. Objects left to the collector are collected
    before the block ends."""
    ignored = []
    previous, sys.unraisablehook = sys.unraisablehook, ignored.append
    try:
        yield
        gc.collect()
    finally:
        sys.unraisablehook = previous
    assert not ignored, f"'Exception ignored' on stderr: {[f'{u.object}: {u.exc_value!r}' for u in ignored]}"


def assert_refused(alg_id: str, params: dict, *contains: str, watch=(), capfd=None) -> str:
    """Run ``alg_id`` with ``params`` through processing.run; it must raise QgsProcessingException
    whose message contains every string of ``contains`` (case-insensitive), and leave the files and
    folders in ``watch`` unchanged. No error may reach Python's unraisable hook during the run (what
    prints 'Exception ignored' on stderr; objects it leaves to the collector are collected first), and
    with pytest's ``capfd`` fixture the captured stderr must hold no traceback. Returns the message."""
    before = snapshot(*watch)
    with no_unraisable(), pytest.raises(QgsProcessingException) as info:
        processing.run(alg_id, params, feedback=QgsProcessingFeedback())
    message = str(info.value)
    for text in contains:
        assert text.lower() in message.lower(), f"{text!r} not in the message: {message}"
    assert "Traceback" not in message
    if capfd is not None:
        assert_clean_stderr(capfd.readouterr().err)
    assert_unchanged(before, watch)
    return message


def assert_refused_cli(qgis_process, alg_id: str, params: dict, *contains: str, watch=()) -> str:
    """The same through qgis_process (a fixture of conftest): exit code not 0, no Python
    traceback (nor 'Exception ignored') on either stream, the message on one of them. Returns
    stdout + stderr."""
    before = snapshot(*watch)
    done: subprocess.CompletedProcess = qgis_process("run", alg_id, "--", *(f"{k}={v}" for k, v in params.items()))
    text = done.stdout + done.stderr
    assert done.returncode != 0, f"exit 0 for bad input: {text}"
    assert_clean_stderr(text)
    for t in contains:
        assert t.lower() in text.lower(), f"{t!r} not in the output: {text}"
    assert_unchanged(before, watch)
    return text


class LogFeedback(QgsProcessingFeedback):
    """Feedback that keeps the algorithm's log: ``lines`` (info and warnings, in order), ``warnings``."""

    def __init__(self):
        super().__init__()
        self.lines, self.warnings = [], []

    def pushInfo(self, info):  # noqa: N802 (QGIS API name)
        self.lines.append(info)

    def pushWarning(self, warning):  # noqa: N802
        self.lines.append(warning)
        self.warnings.append(warning)


def huge_vrt(dem, vrt: Path, factor: int = 1000) -> str:
    """A VRT at ``vrt`` of the DEM file ``dem`` at 1/factor of its pixel size (the simulator's: ~2
    million pixels square, ~16 TB of heights, for factor 1000), naming the DEM relative to its folder."""
    src = gdal.Open(str(dem))
    gt, nx, ny = src.GetGeoTransform(), src.RasterXSize * factor, src.RasterYSize * factor
    srs = src.GetProjection().replace('"', "&quot;")
    vrt.write_text(f"""<VRTDataset rasterXSize="{nx}" rasterYSize="{ny}">
  <SRS>{srs}</SRS>
  <GeoTransform>{gt[0]}, {gt[1] / factor}, 0, {gt[3]}, 0, {gt[5] / factor}</GeoTransform>
  <VRTRasterBand dataType="Float32" band="1">
    <NoDataValue>-32768</NoDataValue>
    <SimpleSource>
      <SourceFilename relativeToVRT="1">{os.path.relpath(dem, vrt.parent)}</SourceFilename>
      <SourceBand>1</SourceBand>
      <SrcRect xOff="0" yOff="0" xSize="{src.RasterXSize}" ySize="{src.RasterYSize}"/>
      <DstRect xOff="0" yOff="0" xSize="{nx}" ySize="{ny}"/>
    </SimpleSource>
  </VRTRasterBand>
</VRTDataset>""")
    return str(vrt)
