"""Fixtures for tests in real QGIS (pytest-qgis 2.x): the plugin as a package, its provider
registered once per session, and one small simulated scene shared by all tests.

The repository folder's name is not fixed (CI clones it anywhere), so the plugin is reached
through a symlink ``pushbroom_adjust`` -> repository root in a temporary plugin folder; the
same folder is QGIS_PLUGINPATH for the qgis_process tests.
"""
import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest
from qgis.core import QgsApplication

from tests.support.hostile import assert_clean_stderr
from tests.support.paths import PLUGIN, QGIS_PROCESS, REPO


@pytest.fixture(scope="session")
def plugin_path(tmp_path_factory) -> Path:
    """A folder holding only the plugin (as a symlink named PLUGIN), on sys.path."""
    folder = tmp_path_factory.mktemp("plugins")
    (folder / PLUGIN).symlink_to(REPO, target_is_directory=True)
    sys.path.insert(0, str(folder))
    return folder


@pytest.fixture(scope="session")
def plugin(plugin_path):
    """The plugin package, imported as QGIS imports it."""
    return importlib.import_module(PLUGIN)


@pytest.fixture(scope="session")
def plugin_instance(qgis_iface, qgis_processing, plugin):
    """The plugin as QGIS starts it: classFactory, then initProcessing (which registers the
    provider). The fixture keeps the Python references alive: without them the provider would
    be garbage-collected under the registry. Unloading at the end removes the provider."""
    instance = plugin.classFactory(qgis_iface)
    instance.initProcessing()
    yield instance
    instance.unload()
    assert QgsApplication.processingRegistry().providerById("pushbroom") is None


@pytest.fixture(scope="session")
def provider(plugin_instance):
    """The registered 'pushbroom' provider."""
    return plugin_instance.provider


@pytest.fixture(scope="session")
def simulated(provider, tmp_path_factory) -> dict:
    """A small simulated CBERS-02B scene (few GCPs), made once through pushbroom:simulatescene.

    Returns the algorithm's results: ONBOARD_SCENE, TRUE_SCENE, GCPS, DEM paths and OUTPUT_FOLDER.
    """
    import processing
    out = tmp_path_factory.mktemp("sim")
    return processing.run("pushbroom:simulatescene", {"PRESET": "cbers02b_hrc", "SEED": 3, "N_SCENES": 1, "N_GCPS": 12,
                                                      "IMAGE_NOISE": 0.0, "RENDER": False,
                                                      "OUTPUT_FOLDER": str(out)})


@pytest.fixture(scope="session")
def qgis_process(plugin_path, tmp_path_factory):
    """Run qgis_process with the plugin enabled in a throw-away profile; returns a function
    (*args) -> CompletedProcess."""
    env = dict(os.environ, QGIS_PLUGINPATH=str(plugin_path), QT_QPA_PLATFORM="offscreen",
               QGIS_CUSTOM_CONFIG_PATH=str(tmp_path_factory.mktemp("profile")))

    def run(*args):
        return subprocess.run([QGIS_PROCESS, *args], env=env, capture_output=True, text=True, timeout=600,
                              stdin=subprocess.DEVNULL)

    enabled = run("plugins", "enable", PLUGIN)
    assert enabled.returncode == 0, enabled.stdout + enabled.stderr
    return run


@pytest.fixture(scope="session")
def three_line(provider, tmp_path_factory) -> dict:
    """A small simulated TH-1 three-line scene with 40 tie points (tie_points.csv), made once
    through pushbroom:simulatescene; its results (ONBOARD_SCENE, TRUE_SCENE, TIE_POINTS, ...)."""
    import processing
    out = tmp_path_factory.mktemp("th1")
    return processing.run("pushbroom:simulatescene", {"PRESET": "th1_tlc", "SEED": 3, "N_SCENES": 1, "N_GCPS": 10,
                                                      "N_TIE_POINTS": 40, "IMAGE_NOISE": 0.3, "RENDER": False,
                                                      "OUTPUT_FOLDER": str(out)})


@pytest.fixture(autouse=True)
def hostile_stderr_is_clean(request):
    """Every test of the hostile suite (test_hostile_*.py): whatever it leaves on stderr (the
    process's file descriptor 2: QGIS, GDAL and Python alike) holds no traceback and no
    'Exception ignored' (see tests/support/hostile.py), refused inputs and accepted ones alike."""
    if not request.module.__name__.rsplit(".", 1)[-1].startswith("test_hostile"):
        yield
        return
    capfd = request.getfixturevalue("capfd")
    yield
    assert_clean_stderr(capfd.readouterr().err)
