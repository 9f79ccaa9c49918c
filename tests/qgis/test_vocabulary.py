"""One parameter vocabulary across every algorithm of the provider (issue 15).

A parameter name is one concept: wherever it appears it has the same type, description, help
(docs/parameters.md; a page may add a sentence for its algorithm), default and, for enumerations, the same named values in the same order. Enumerations take
value names (static strings), never option numbers; enumerations of the same values list them
in the same order under any name (the DEM_DATUM/Z_DATUM mismatch of issue 15 was geoid,
ellipsoid against ellipsoid, geoid). vocabulary_problems() is shown failing on deliberately
broken copies of 'groundtoimage'.
"""
import importlib
import re

import pytest
from qgis.core import (QgsProcessingContext, QgsProcessingModelAlgorithm, QgsProcessingParameterDefinition,
                       QgsProcessingParameterEnum, QgsProcessingParameterNumber)

from tests.support.paths import PLUGIN, REPO

# QGIS's convention (native:buffer, gdal:warpreproject): the algorithm's main input and output,
# whose type is the algorithm's own (a raster for orthorectify, a point layer for groundtoimage);
# INPUT_FILE is the main input given as a file (GCPs: CSV or .points; tie points: CSV);
# OUTPUT_FOLDER the folder of the algorithm's own files (a simulation, a block's adjusted scenes).
GENERIC = {"INPUT", "INPUT_FILE", "OUTPUT", "OUTPUT_FOLDER"}
VALUE_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
# What must agree between a model's input and the algorithm parameter of the same name; a
# shipped model is a worked example with its own defaults and explanations (N_GCPS 2000).
MODEL_KEYS = ("parameter_type", "options", "uses_static_strings", "allow_multiple", "data_type")


def _signature(definition) -> dict:
    """The whole definition (type, description, help, default, options, limits, ...) but the
    advanced flag, which only says where the dialog shows it."""
    signature = dict(definition.toVariantMap())
    signature["flags"] = int(signature["flags"]) & ~int(QgsProcessingParameterDefinition.FlagAdvanced)
    signature["class"] = type(definition).__name__
    return signature


def _one_scene_words(signature: dict, definition) -> dict:
    """The description SCENE has where there is no SCENES, when ``definition`` has exactly the
    label of the shared definition with SCENES (ui.parameters.scene(optional=True)); else unchanged."""
    vocabulary = importlib.import_module(f"{PLUGIN}.ui.parameters")
    if definition.description() != vocabulary.scene(optional=True).description():
        return {}
    return {"description": vocabulary.scene().description()}


def _added_to(alg) -> set[str]:
    """The shared parameters to whose help the algorithm's page adds a sentence (its entry links to
    docs/parameters.md and has a text of its own): their help differs there by design."""
    help_module = importlib.import_module(f"{PLUGIN}.ui.help")
    return {e.name for e in help_module.page_entries(help_module.help_page(alg.name())) if e.shared and e.text}


def _enumeration_problems(where: str, definition, seen: dict) -> list[str]:
    problems = []
    options = list(definition.options())
    if not definition.usesStaticStrings():
        problems.append(f"{where}: enumeration by option number (usesStaticStrings is off)")
    problems += [f"{where}: value {o!r} is not a short lower-case name" for o in options if not VALUE_NAME.match(o)]
    default = definition.defaultValue()
    if default is not None and default not in options:
        problems.append(f"{where}: default {default!r} is not one of its values {options}")
    first = seen.setdefault(frozenset(options), (where, options))
    if first[1] != options:
        problems.append(f"{where}: values {options} in another order than {first[0]} {first[1]}")
    return problems


def vocabulary_problems(algorithms) -> list[str]:
    """Every departure from one vocabulary among ``algorithms`` (initialised algorithms)."""
    problems, first, enumerations = [], {}, {}
    ordered = sorted(algorithms, key=lambda a: isinstance(a, QgsProcessingModelAlgorithm))  # models last
    for alg in ordered:
        model = isinstance(alg, QgsProcessingModelAlgorithm)
        added = set() if model else _added_to(alg)
        for definition in alg.parameterDefinitions():
            name, where = definition.name(), f"{alg.id()} {definition.name()}"
            if isinstance(definition, QgsProcessingParameterEnum):
                problems += _enumeration_problems(where, definition, enumerations)
            if name in GENERIC:
                continue
            signature = _signature(definition)
            if name in added:  # compared as the shared help it adds to
                signature["help"] = importlib.import_module(f"{PLUGIN}.ui.help").shared_help(name)
            if name in ("SCENE", "OUTPUT_SCENE") and alg.parameterDefinition("SCENES") is not None:
                # optional where a block's SCENES may replace it (a block writes its scenes elsewhere), and only there
                signature["flags"] = int(signature["flags"]) & ~int(QgsProcessingParameterDefinition.FlagOptional)
                if name == "SCENE":  # there its label and help (the page's addition) say that SCENE or SCENES is needed
                    signature.update(_one_scene_words(signature, definition))
            if name not in first:
                if not model:
                    first[name] = (alg.id(), signature)
                continue
            other, expected = first[name]
            keys = MODEL_KEYS + ("class",) if model else sorted(set(signature) | set(expected))
            differing = [k for k in keys if signature.get(k) != expected.get(k)]
            if differing:
                problems.append(f"{where} differs from {other} {name} in " + ", ".join(
                    f"{k} ({signature.get(k)!r} against {expected.get(k)!r})" for k in differing))
    return problems


def test_the_provider_speaks_one_vocabulary(provider):
    algorithms = provider.algorithms()
    assert len(algorithms) == 20  # 16 algorithms and the four shipped models
    assert vocabulary_problems(algorithms) == []


def test_shared_concepts_are_shared(provider):
    """The checks above bite: the shared names do appear in several algorithms."""
    counts = {}
    for alg in provider.algorithms():
        for definition in alg.parameterDefinitions():
            counts[definition.name()] = counts.get(definition.name(), 0) + 1
    assert counts["DEM_DATUM"] == 11 and counts["HEIGHT"] == 10 and counts["SCENE"] == 14
    assert counts["Z_DATUM"] == 3 and counts["CAMERA"] == 8 and counts["CHECK_FRACTION"] == 4
    assert counts["RESAMPLING"] == 2 and counts["OUTPUT_SCENE"] == 2
    assert counts["COL_FIELD"] == 3 and counts["ROW_FIELD"] == 3
    assert counts["ID_FIELD"] == 2 and counts["CAMERA_FIELD"] == 2 and counts["SIGMA_PX"] == 2
    assert counts["SIGMA_PX_FIELD"] == 2 and counts["IMAGE_LINES"] == 3  # importlines, snaplines, the model with lines
    assert counts["INPUTS"] == 2 and counts["SEARCH_RANGE"] == 2 and counts["WINDOW"] == 2
    assert counts["RENDER"] == counts["IMAGE_SIZE"] == counts["N_TIE_POINTS"] == 2  # the two simulators


def _copy_of_groundtoimage(plugin, change):
    """An initialised copy of 'groundtoimage' with ``change(alg)`` applied to its parameters."""
    base = importlib.import_module(f"{PLUGIN}.ui.algorithms.groundtoimage").GroundToImageAlgorithm

    class Changed(base):
        ID = "groundtoimage_changed"

        def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
            super().initAlgorithm(config)
            change(self)

    alg = Changed()
    alg.initAlgorithm({})
    return alg


def _replace(alg, definition):
    alg.removeParameter(definition.name())
    alg.addParameter(definition)


def _enum(name, options, default, static=True, optional=False):
    return QgsProcessingParameterEnum(name, "changed", options=options, defaultValue=default, optional=optional,
                                      usesStaticStrings=static)


BROKEN = {
    # the same parameter name, its values reversed
    "DEM_DATUM reordered": (lambda a: _replace(a, _enum("DEM_DATUM", ["ellipsoid", "geoid"], "geoid")),
                            ["groundtoimage_changed DEM_DATUM: values ['ellipsoid', 'geoid'] in another order",
                             "groundtoimage_changed DEM_DATUM differs from pushbroom:"]),
    # issue 15's mismatch: Z_DATUM listing the datums in the other order than DEM_DATUM
    "Z_DATUM as before issue 15": (
        lambda a: _replace(a, _enum("Z_DATUM", ["ellipsoid", "geoid"], None, optional=True)),
        ["groundtoimage_changed Z_DATUM: values ['ellipsoid', 'geoid'] in another order than"]),
    "an enumeration by option number": (
        lambda a: _replace(a, _enum("DEM_DATUM", ["geoid", "ellipsoid"], 0, static=False)),
        ["groundtoimage_changed DEM_DATUM: enumeration by option number",
         "groundtoimage_changed DEM_DATUM: default 0 is not one of its values"]),
    "readable labels as values": (
        lambda a: _replace(a, _enum("DEM_DATUM", ["Geoid (EGM96)", "Ellipsoid (WGS84)"], "Geoid (EGM96)")),
        ["groundtoimage_changed DEM_DATUM: value 'Geoid (EGM96)' is not a short lower-case name"]),
    "another default": (
        lambda a: a.parameterDefinition("HEIGHT").setDefaultValue(100.0),
        ["groundtoimage_changed HEIGHT differs from pushbroom:", "default (100.0 against 0.0)"]),
    "another type": (
        lambda a: _replace(a, QgsProcessingParameterNumber("CAMERA", "Camera (name or index)", optional=True)),
        ["groundtoimage_changed CAMERA differs from pushbroom:", "class ('QgsProcessingParameterNumber' against "
                                                                 "'QgsProcessingParameterString')"]),
    "another help text": (
        lambda a: a.parameterDefinition("SCENE").setHelp("A scene."),
        ["groundtoimage_changed SCENE differs from pushbroom:", "help ('A scene.' against"]),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_a_broken_copy_is_caught(provider, plugin, case):
    change, expected = BROKEN[case]
    problems = vocabulary_problems([*provider.algorithms(), _copy_of_groundtoimage(plugin, change)])
    assert problems, case
    assert all(p.startswith("groundtoimage_changed ") for p in problems), problems
    for text in expected:
        assert any(text in p for p in problems), f"{text!r} not in {problems}"


def test_enumerations_are_read_by_name_only(provider):
    """QGIS 3.22's parameterAsEnum reads a value name as option 0 (here 'geoid' for 'ellipsoid'):
    the algorithms read enumerations with ui.parameters.enum_value and never by index."""
    alg = provider.algorithm("footprint")
    assert alg.parameterAsEnum({"DEM_DATUM": "ellipsoid"}, "DEM_DATUM", QgsProcessingContext()) == 0
    sources = sorted((REPO / "ui").rglob("*.py"))
    assert len(sources) >= 11
    assert [str(p) for p in sources if "parameterAsEnum" in p.read_text()] == []


def test_user_visible_texts_go_through_tr_and_group_ids_are_fixed(provider, plugin, monkeypatch):
    """With a translation that marks every text, every algorithm name, group and parameter
    description and the provider's name come out marked; the group ids do not change."""
    parameters = importlib.import_module(f"{PLUGIN}.ui.parameters")

    class Marking:
        @staticmethod
        def translate(context, text):
            assert context == parameters.TR_CONTEXT
            return f"«{text}»"

    group_ids = {alg.id(): alg.groupId() for alg in provider.algorithms()}
    monkeypatch.setattr(parameters, "QCoreApplication", Marking)
    assert provider.name() == "«Pushbroom Adjust»"
    for alg in provider.algorithms():
        if isinstance(alg, QgsProcessingModelAlgorithm):
            continue
        fresh = alg.createInstance()
        fresh.initAlgorithm({})
        assert fresh.displayName().startswith("«") and fresh.group().startswith("«"), alg.id()
        assert fresh.groupId() == group_ids[alg.id()] and re.fullmatch("[a-z]+", fresh.groupId()), alg.id()
        assert fresh.shortHelpString().startswith("<p>«"), alg.id()
        untranslated = [d.name() for d in fresh.parameterDefinitions() if not d.description().startswith("«")]
        assert untranslated == [], f"{alg.id()}: descriptions not through tr(): {untranslated}"
        outputs = [o.name() for o in fresh.outputDefinitions() if not o.description().startswith("«")]
        assert outputs == [], f"{alg.id()}: output descriptions not through tr(): {outputs}"


def test_qgis_process_help_lists_the_value_names(provider, qgis_process):
    """qgis_process 3.22 lists static-string values with their positions ('- 1: ellipsoid') and
    the generic 'Number of selected option'; the parameter's help says to give the name."""
    checked = 0
    for alg in provider.algorithms():
        enums = [d for d in alg.parameterDefinitions() if isinstance(d, QgsProcessingParameterEnum)]
        if not enums or isinstance(alg, QgsProcessingModelAlgorithm):
            continue
        done = qgis_process("help", alg.id())
        assert done.returncode == 0, done.stdout + done.stderr
        for d in enums:
            section = done.stdout.split(f"\n{d.name()}: ", 1)[1].split("Acceptable values", 1)[0]
            assert "option numbers are refused" in section, (alg.id(), d.name())
            for k, value in enumerate(d.options()):
                assert f"- {k}: {value}\n" in section and f" {value}: " in section, (alg.id(), value)
            checked += 1
    assert checked == 32  # every enumeration of every algorithm (DEM_DATUM in eleven of them)


def test_the_readme_demo_and_models_use_value_names():
    """No enumeration is passed by number in the README's and docs' command lines, the demo or the models."""
    names = ("DEM_DATUM", "Z_DATUM", "HEIGHT_SOURCE", "POSITION_MODEL", "ATTITUDE_MODEL", "GROUND", "ROBUST",
             "ON_SINGULAR", "RESAMPLING", "PRESET", "INTERIOR_SELECTION")
    by_number = re.compile(r"\b(" + "|".join(names) + r")=\d")
    pages = sorted((REPO / "docs").rglob("*.md"))
    assert len(pages) >= 15  # one per algorithm at least
    for path in [REPO / "README.md", REPO / "scripts" / "demo.sh", *pages]:
        assert by_number.findall(path.read_text()) == [], path
    for model in (REPO / "resources" / "models").glob("*.model3"):
        text = model.read_text()
        for name in names:
            for block in text.split(f'<Option name="{name}" type="List">')[1:]:
                static = block.split("</Option>", 2)[0]
                assert 'static_value" type="int"' not in static, (model.name, name)


def test_the_toolbox_lists_and_returns_the_value_names(provider):
    """QGIS 3.22's drop-down of a static-string enumeration shows the value names themselves (it
    has no separate labels: the help says what each means) and gives back the name chosen; an
    optional one starts at its default ('[Not selected]' without one; DEM_DATUM is optional so that models
    written before an algorithm took a DEM stay valid, and an unset one is its default, geoid)."""
    from qgis.gui import QgsGui, QgsProcessingGui
    from qgis.PyQt.QtWidgets import QComboBox
    context = QgsProcessingContext()
    alg = provider.algorithm("groundtoimage")
    for name, shown, first in (("DEM_DATUM", ["[Not selected]", "geoid", "ellipsoid"], "geoid"),
                               ("Z_DATUM", ["[Not selected]", "geoid", "ellipsoid"], None)):
        wrapper = QgsGui.processingGuiRegistry().createParameterWidgetWrapper(alg.parameterDefinition(name),
                                                                             QgsProcessingGui.Standard)
        combo = wrapper.createWrappedWidget(context)
        assert isinstance(combo, QComboBox)
        assert [combo.itemText(i) for i in range(combo.count())] == shown
        assert wrapper.parameterValue() == first
        combo.setCurrentIndex(shown.index("ellipsoid"))
        assert wrapper.parameterValue() == "ellipsoid"
