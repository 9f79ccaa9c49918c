"""The plugin as a user gets it: scripts/package.sh builds the zip, which is installed into a fresh
QGIS profile the way *Install from ZIP* does (unzipped into <profile>/python/plugins/), enabled and
run with qgis_process, with nothing pointing at this repository (no QGIS_PLUGINPATH, no PYTHONPATH).
"""
import ast
import configparser
import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from osgeo import ogr

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.products.footprint import footprints
from pushbroom_adjust.core.formats import load_scene

from tests.support.paths import PLUGIN, QGIS_PROCESS, REPO
from tests.support.provider import ALGORITHMS, MODELS
from tests.support.qgis_process import run_json

CONTENT = ("metadata.txt", "__init__.py", "plugin.py", "LICENSE", "README.md", "docs", "core", "simulation", "ui",
           "resources")
# What the plugin may import besides itself: the standard library and these (QGIS's Python and the
# packages the README's set-up installs).
THIRD_PARTY = {"numpy", "scipy", "pyproj", "osgeo", "matplotlib", "qgis", "processing",
               "distributed"}  # distributed (Dask): optional, only for orthorectify's SCHEDULER
MAX_UPLOAD = 25_000_000  # plugins.qgis.org refuses larger packages


def _metadata(text: str) -> configparser.SectionProxy:
    parser = configparser.ConfigParser(interpolation=None)
    parser.optionxform = str
    parser.read_string(text)
    return parser["general"]


@pytest.fixture(scope="module")
def package(tmp_path_factory) -> Path:
    """The zip built by scripts/package.sh into a temporary folder."""
    out = tmp_path_factory.mktemp("dist")
    done = subprocess.run(["bash", str(REPO / "scripts" / "package.sh"), str(out)], capture_output=True, text=True,
                          timeout=300, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stdout + done.stderr
    version = _metadata((REPO / "metadata.txt").read_text(encoding="utf-8"))["version"]
    path = Path(done.stdout.strip())
    assert path == out / f"{PLUGIN}-{version}.zip" and path.is_file()
    assert [p.name for p in out.iterdir()] == [path.name]  # no temporary file left beside it
    return path


@pytest.fixture(scope="module")
def installed(package, tmp_path_factory) -> Path:
    """A fresh QGIS configuration folder with the zip unzipped into its default profile's plugins."""
    root = tmp_path_factory.mktemp("qgis_config")
    plugins = root / "profiles" / "default" / "python" / "plugins"
    plugins.mkdir(parents=True)
    with zipfile.ZipFile(package) as z:
        z.extractall(plugins)
    return root


def _qgis_process(config: Path, cwd: Path):
    """qgis_process with only `config` as QGIS's settings: no plugin path or Python path to the repository."""
    env = {k: v for k, v in os.environ.items() if k not in ("QGIS_PLUGINPATH", "PYTHONPATH", "PYTHONHOME")}
    env.update(QGIS_CUSTOM_CONFIG_PATH=str(config), QT_QPA_PLATFORM="offscreen")

    def run(*args):
        return subprocess.run([QGIS_PROCESS, *args], env=env, cwd=cwd, capture_output=True, text=True, timeout=600,
                              stdin=subprocess.DEVNULL)
    return run


def test_zip_holds_exactly_the_tracked_plugin_files_in_one_folder(package):
    with zipfile.ZipFile(package) as z:
        names = z.namelist()
        assert z.testzip() is None
    files = {n for n in names if not n.endswith("/")}
    tracked = subprocess.run(["git", "ls-files", "-z", "--", *CONTENT], cwd=REPO, capture_output=True, text=True,
                             check=True).stdout.split("\0")[:-1]
    assert len(tracked) > 40  # the listing really sees the plugin
    assert files == {f"{PLUGIN}/{f}" for f in tracked}
    assert names[0] == f"{PLUGIN}/"  # plugins.qgis.org takes the package name from the first entry
    assert {n.split("/")[0] for n in names} == {PLUGIN}
    parts = {p for n in names for p in n.split("/")[1:]}
    for unwanted in ("tests", "scripts", ".ci", ".venv", "__pycache__", "out", "dist", ".git", ".gitignore"):
        assert unwanted not in parts, unwanted
    assert not any(n.endswith((".pyc", ".part")) for n in names)
    assert package.stat().st_size < MAX_UPLOAD


def test_zip_metadata_is_complete_and_truthful(package):
    with zipfile.ZipFile(package) as z:
        text = z.read(f"{PLUGIN}/metadata.txt").decode("utf-8")
        names = set(z.namelist())
        licence = z.read(f"{PLUGIN}/LICENSE").decode("utf-8")
    meta = _metadata(text)
    for key in ("name", "description", "about", "version", "qgisMinimumVersion", "author", "changelog"):
        assert meta.get(key, "").strip(), key
    assert "example." not in text.lower()  # no placeholder addresses: a field is left out instead
    assert package.name == f"{PLUGIN}-{meta['version']}.zip"
    assert meta["changelog"].split()[0] == meta["version"]  # the newest entry is this version
    assert f"{PLUGIN}/{meta['icon']}" in names
    with zipfile.ZipFile(package) as z:
        ui_source = "".join(z.read(n).decode("utf-8") for n in z.namelist() if n.startswith(f"{PLUGIN}/ui/"))
    resources = re.findall(r'"([\w./-]+\.(?:qml|svg|model3))"', ui_source)  # files the code names
    resources = [r for r in resources if not r.startswith("/")]  # but QGIS's theme icons ("/mActionPan.svg")
    assert "icon.svg" in resources and "gcps.qml" in resources
    shipped = {n.rsplit("/", 1)[-1] for n in names if n.startswith(f"{PLUGIN}/resources/")}
    assert set(resources) <= shipped
    assert "GNU GENERAL PUBLIC LICENSE" in licence and "Version 2, June 1991" in licence
    assert "any later version" in meta["about"]


def _outside_imports(files: dict) -> list:
    """Imports in the given {zip name: source} that reach outside the plugin's folder: absolute imports of
    anything but the standard library and THIRD_PARTY, relative imports of modules not in the zip."""
    modules = {n[:-len("/__init__.py")] if n.endswith("/__init__.py") else n[:-3]: n for n in files}

    def defines(module: str, name: str) -> bool:  # a submodule, or a name bound at the top of the module
        if f"{module}/{name}" in modules:
            return True
        tree = ast.parse(files[modules[module]]) if module in modules else ast.Module(body=[])
        bound = {getattr(t, "id", None) for n in tree.body if isinstance(n, (ast.Assign, ast.AnnAssign))
                 for t in getattr(n, "targets", [getattr(n, "target", None)])}
        bound |= {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
        return name in bound

    bad = []
    for name, source in files.items():
        folder = name.rsplit("/", 1)[0].split("/")
        for node in ast.walk(ast.parse(source, filename=name)):
            if isinstance(node, ast.Import):
                bad += [f"{name}: import {a.name}" for a in node.names
                        if a.name.split(".")[0] not in sys.stdlib_module_names | THIRD_PARTY]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                if node.module.split(".")[0] not in sys.stdlib_module_names | THIRD_PARTY:
                    bad.append(f"{name}: from {node.module} import ...")
            elif isinstance(node, ast.ImportFrom):
                base = folder[:len(folder) - node.level + 1]
                target = "/".join(base + (node.module.split(".") if node.module else []))
                found = target in modules if node.module else all(defines(target, a.name) for a in node.names)
                if not base or not found:
                    bad.append(f"{name}: from {'.' * node.level}{node.module or ''} import ...")
    return bad


def test_plugin_imports_stay_inside_its_folder(package):
    with zipfile.ZipFile(package) as z:
        files = {n: z.read(n).decode("utf-8") for n in z.namelist() if n.endswith(".py")}
    assert len(files) > 20
    assert _outside_imports(files) == []
    # The scan catches each way out of the folder.
    probe = {f"{PLUGIN}/__init__.py": "", f"{PLUGIN}/ui/a.py": (
        "from ..core import x\nfrom ...elsewhere import y\nimport tests.data\nfrom core.dem import Dem\n"
        "from . import missing\nfrom .. import ui\nfrom . import helper\nimport numpy, os.path\n"),
             f"{PLUGIN}/ui/__init__.py": "def helper():\n    pass\n"}
    assert _outside_imports(probe) == [f"{PLUGIN}/ui/a.py: " + s for s in (
        "from ..core import ...", "from ...elsewhere import ...", "import tests.data",
        "from core.dem import ...", "from . import ...")]


def test_installed_plugin_imports_nothing_from_the_repository(installed):
    """Every module of the installed copy imported by a clean Python (-I: no PYTHONPATH, no script folder):
    none comes from the repository, and no stray top-level 'core' or 'ui' appears."""
    script = """if True:
        import importlib, json, pkgutil, sys
        from pathlib import Path
        plugins, repo = sys.argv[1], Path(sys.argv[2]).resolve()
        sys.path.insert(0, plugins)
        package = importlib.import_module(sys.argv[3])
        names = [m.name for m in pkgutil.walk_packages(package.__path__, package.__name__ + ".")]
        for name in names:
            importlib.import_module(name)
        files = {n: Path(m.__file__).resolve() for n, m in list(sys.modules.items()) if getattr(m, "__file__", None)}
        print(json.dumps({"imported": names,
                          "from_repo": sorted(n for n, f in files.items() if f.is_relative_to(repo)),
                          "stray": sorted(n for n in sys.modules if n.split(".")[0] in ("core", "simulation", "ui", "tests"))}))
    """
    plugins = installed / "profiles" / "default" / "python" / "plugins"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    done = subprocess.run(["/usr/bin/python3", "-I", "-c", script, str(plugins), str(REPO), PLUGIN], env=env,
                          cwd=plugins, capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stdout + done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert f"{PLUGIN}.ui.provider" in result["imported"] and f"{PLUGIN}.core.adjust.engine" in result["imported"]
    assert result["from_repo"] == [] and result["stray"] == []


def test_installed_zip_enables_and_runs_in_a_fresh_profile(installed, tmp_path):
    # Without the zip the same environment knows no such plugin: nothing else leads QGIS to the repository.
    bare = tmp_path / "bare_config"
    (bare / "profiles" / "default" / "python" / "plugins").mkdir(parents=True)
    refused = _qgis_process(bare, tmp_path)("plugins", "enable", PLUGIN)
    assert refused.returncode != 0

    run = _qgis_process(installed, tmp_path)
    enabled = run("plugins", "enable", PLUGIN)
    assert enabled.returncode == 0, enabled.stdout + enabled.stderr
    listed = run("list")
    assert listed.returncode == 0, listed.stderr
    for alg in ALGORITHMS + MODELS:  # the models come from the zip's resources/models/
        assert f"\t{alg}\t" in listed.stdout, alg
    # the help is the summary of the algorithm's page, which the zip carries, with a link to it
    page = installed / "profiles" / "default" / "python" / "plugins" / PLUGIN / "docs" / "algorithms" / "bundleadjust.md"
    helped = run("help", "pushbroom:bundleadjust")
    assert helped.returncode == 0 and page.is_file(), helped.stderr
    assert f'<a href="{page.as_uri()}">' in helped.stdout and "Self-calibrating bundle adjustment" in helped.stdout
    # and each parameter's help is its entry there, or in docs/parameters.md for a shared one (issue 29)
    assert "Comma-separated names, 'name=sigma' for a weighted one" in helped.stdout  # INTERIOR, its page
    assert "The sensor model of the scene: a scene JSON" in helped.stdout  # SCENE, docs/parameters.md
    sim = run_json(run, "pushbroom:simulatescene", SEED=3, N_GCPS=12, OUTPUT_FOLDER=tmp_path / "sim")
    out = tmp_path / "footprint.gpkg"
    run_json(run, "pushbroom:footprint", SCENE=sim["TRUE_SCENE"], DEM=sim["DEM"], DEM_DATUM="geoid", SAMPLES=16,
              OUTPUT=out)

    ds = ogr.Open(str(out))  # kept: its layer dies with it
    got = [(f.GetField("camera"), f.GetField("area_km2")) for f in ds.GetLayer(0)]
    truth = footprints(load_scene(sim["TRUE_SCENE"]), Dem(sim["DEM"], "geoid"), samples_per_edge=16)
    assert [c for c, _ in got] == [fp.camera for fp in truth] == ["HRC"]
    assert np.allclose([a for _, a in got], [fp.area_km2 for fp in truth], rtol=1e-9)
    assert 500 < got[0][1] < 1500  # a CBERS-02B HRC scene: ~29 km square
