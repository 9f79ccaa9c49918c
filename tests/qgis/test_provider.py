"""The plugin loads in QGIS and its provider lists its algorithms with complete help."""
import importlib

from qgis.core import QgsApplication, QgsProcessingModelAlgorithm

from tests.support.paths import PLUGIN
from tests.support.provider import ALGORITHMS, MODELS


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
            assert p.name() in alg.shortHelpString(), f"{alg.id()}: {p.name()} missing from the help"


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
