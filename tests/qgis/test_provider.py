"""The plugin loads in QGIS and its provider lists its algorithms with complete help."""
import ast
import importlib
from pathlib import Path

from qgis.core import QgsApplication, QgsProcessingModelAlgorithm, QgsProcessingParameterDefinition

from tests.support.paths import PLUGIN
from tests.support.provider import ALGORITHMS, MODELS

PLUGIN_ROOT = Path(importlib.import_module(PLUGIN).__file__).resolve().parent


def test_provider_lists_its_algorithms(provider):
    assert provider.id() == "pushbroom" and provider.name() == "Pushbroom Adjust"
    assert not provider.icon().isNull() and provider.svgIconPath().endswith("icon.svg")
    assert sorted(a.id() for a in provider.algorithms()) == sorted(ALGORITHMS + MODELS)
    registry = QgsApplication.processingRegistry()
    for alg_id in ALGORITHMS + MODELS:
        assert registry.algorithmById(alg_id) is not None, alg_id


def test_every_parameter_has_help_and_an_uppercase_name(provider):
    for alg in provider.algorithms():
        if isinstance(alg, QgsProcessingModelAlgorithm):
            continue  # a model's parameters are named by QGIS after its steps (tests/qgis/test_model.py)
        for p in alg.parameterDefinitions():
            assert p.name() == p.name().upper(), f"{alg.id()}: {p.name()}"
            assert len(p.help()) > 20, f"{alg.id()}: parameter {p.name()} has no help text"


def test_every_dialog_is_short_and_its_help_links_to_its_docs_page(provider):
    """Issue 30: at most 8 inputs shown (outputs not counted; the rest under 'Advanced parameters'), a short
    help from docs/algorithms/<id>.md that names every input shown by its id in parentheses, and a link to
    that page (also helpUrl)."""
    for alg in provider.algorithms():
        if isinstance(alg, QgsProcessingModelAlgorithm):
            continue
        inputs = [p for p in alg.parameterDefinitions() if not p.isDestination()]
        shown = [p.name() for p in inputs if not p.flags() & QgsProcessingParameterDefinition.FlagAdvanced]
        assert len(shown) <= 8, f"{alg.id()} shows {len(shown)} inputs: {shown}"
        help_text, page = alg.shortHelpString(), PLUGIN_ROOT / "docs" / "algorithms" / f"{alg.name()}.md"
        assert page.is_file() and alg.helpUrl() == page.as_uri(), alg.id()
        assert 300 < len(help_text) <= 2500, f"{alg.id()}: help of {len(help_text)} characters"
        assert f'<a href="{page.as_uri()}">' in help_text, alg.id()
        missing = [name for name in shown if f"(<code>{name}</code>)" not in help_text]
        assert missing == [], f"{alg.id()}: inputs shown but not in the help: {missing}"
        assert "<p>" in help_text and "**" not in help_text and "`" not in help_text, alg.id()  # rendered


def test_bundleadjust_shows_scenes_control_and_interior_in_the_order_of_work(provider):
    alg = provider.algorithm("bundleadjust")
    inputs = [p for p in alg.parameterDefinitions() if not p.isDestination()]
    shown = [p.name() for p in inputs if not p.flags() & QgsProcessingParameterDefinition.FlagAdvanced]
    assert shown == ["SCENE", "SCENES", "GCPS", "TIE_POINTS", "LINES", "INTERIOR"]
    names = [p.name() for p in inputs]
    order = ["INTERIOR", "POSITION_MODEL", "SCENE_SIGMAS", "GROUND", "ROBUST", "ON_SINGULAR", "RESIDUAL_SCALE"]
    assert [names.index(n) for n in order] == sorted(names.index(n) for n in order)
    scene, scenes = alg.parameterDefinition("SCENE"), alg.parameterDefinition("SCENES")
    assert "Scenes of the block" in scene.description() and "Scene" in scenes.description()
    assert "one of them" in scene.help() and "one of them" in scenes.help()
    for name in ("ATTITUDE_SIGMA", "RPC_SIGMA"):  # unset: empty, never 0.000000
        sigma = alg.parameterDefinition(name)
        assert sigma.defaultValue() is None and sigma.flags() & QgsProcessingParameterDefinition.FlagOptional


def test_no_help_text_in_the_code(provider):
    """Issue 29: help lives in docs/algorithms/; no string literal in ui/ (docstrings aside) exceeds 300 characters."""
    long_ones = []
    for path in sorted((PLUGIN_ROOT / "ui").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                      if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                      and node.body and isinstance(node.body[0], ast.Expr)}
        long_ones += [f"{path.name}:{node.lineno}" for node in ast.walk(tree)
                      if isinstance(node, ast.Constant) and isinstance(node.value, str) and len(node.value) > 300
                      and id(node) not in docstrings]
    assert long_ones == []


def test_the_plugin_registers_its_provider_once(provider, plugin_instance):
    registry = QgsApplication.processingRegistry()
    assert registry.providerById("pushbroom") is provider is plugin_instance.provider
    assert [p.id() for p in registry.providers()].count("pushbroom") == 1


def test_metadata_declares_a_processing_provider():
    from configparser import ConfigParser
    meta = ConfigParser()
    meta.read(importlib.import_module(PLUGIN).__file__.replace("__init__.py", "metadata.txt"))
    general = meta["general"]
    assert general["name"] == "Pushbroom Adjust" and general["hasProcessingProvider"] == "yes"
    assert general["qgisMinimumVersion"] == "3.22" and general["icon"].endswith(".svg")


def test_no_algorithm_registers_an_output_twice(provider):
    """A destination parameter makes its own output: registering it again is the start-up line
    'Duplicate output OUTPUT_FOLDER registered for alg simulatescene' (a CRITICAL Processing message)."""
    logged = []

    def keep(text, tag, level):
        logged.append(text)

    QgsApplication.messageLog().messageReceived.connect(keep)
    try:
        for alg in provider.algorithms():
            alg.createInstance().initAlgorithm({})
    finally:
        QgsApplication.messageLog().messageReceived.disconnect(keep)
    assert [t for t in logged if "Duplicate output" in t] == []
    simulate = [a for a in provider.algorithms() if a.id() in ("pushbroom:simulatescene", "pushbroom:simulateblock")]
    assert all(a.outputDefinition("OUTPUT_FOLDER") is not None for a in simulate) and len(simulate) == 2
