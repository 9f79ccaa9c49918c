"""Issue 29: each parameter's help is written once, in the docs (docs/algorithms/<id>.md, section
Parameters; the shared ones in docs/parameters.md), and QGIS shows exactly that text."""
import ast
import importlib
import re

import pytest
from qgis.core import QgsProcessingModelAlgorithm, QgsProcessingParameterDefinition, QgsProcessingParameterEnum

from tests.support.paths import PLUGIN, REPO



@pytest.fixture(scope="module")
def helps(plugin):
    return importlib.import_module(f"{PLUGIN}.ui.help")


def _algorithms(provider):
    return [a for a in provider.algorithms() if not isinstance(a, QgsProcessingModelAlgorithm)]


def _documented(alg) -> list[str]:
    """The parameters and outputs of ``alg`` in the dialog's order (an output of a destination parameter
    is that parameter)."""
    names = [d.name() for d in alg.parameterDefinitions()]
    return names + [o.name() for o in alg.outputDefinitions() if o.name() not in names]


def test_every_page_documents_every_parameter_and_output_in_order_and_nothing_else(provider, helps):
    for alg in _algorithms(provider):
        entries = helps.page_entries(helps.help_page(alg.name()))
        names = [e.name for e in entries]
        stale = [n for n in names if n not in _documented(alg)]
        assert stale == [], f"{alg.name()}.md documents what the algorithm does not have: {stale}"
        assert names == _documented(alg), f"{alg.name()}.md: entries {names}, algorithm {_documented(alg)}"
        empty = [e.name for e in map(helps.resolved, entries) if len(e.text) < 20]
        assert empty == [], f"{alg.name()}.md: entries without a text: {empty}"
    # an asterisk or an angle bracket outside a code span would be read as emphasis or HTML on GitHub
    for entry in [*helps.vocabulary().values(), *(e for a in _algorithms(provider)
                                                 for e in helps.page_entries(helps.help_page(a.name())))]:
        prose = re.sub(r"`[^`]*`", "", " ".join([entry.text, *(m for _, m in entry.values)]))
        assert not re.search(r"\*|<\w", prose), (entry.name, prose)


def test_the_help_qgis_shows_is_the_page_entry(provider, helps, plugin):
    tr = importlib.import_module(f"{PLUGIN}.ui.parameters").tr
    for alg in _algorithms(provider):
        documented = helps.parameter_help(alg.name(), tr)
        for definition in alg.parameterDefinitions():
            assert definition.help() == documented[definition.name()], f"{alg.name()} {definition.name()}"
            assert "**" not in definition.help() and "`" not in definition.help(), definition.name()  # plain text
    footprint = provider.algorithm("footprint")
    page = (REPO / "docs" / "algorithms" / "footprint.md").read_text()
    assert "- **Points per image edge** (`SAMPLES`): How many intervals each edge of the image" in page
    assert footprint.parameterDefinition("SAMPLES").help().startswith("How many intervals each edge of the image "
                                                                      "is divided into; 256 keeps the outline")
    # a shared parameter takes docs/parameters.md's text; a page may add a sentence to it
    scene = helps.shared_help("SCENE")
    assert scene.startswith("The sensor model of the scene: a scene JSON") and "<name>_RPC.TXT" in scene
    assert footprint.parameterDefinition("SCENE").help() == scene
    assert provider.algorithm("importgcps").parameterDefinition("SCENE").help() == \
        f"{scene} Give SCENE or SCENES: one of them."


def test_an_enumeration_documents_its_values_in_order(provider, helps):
    checked = 0
    for alg in _algorithms(provider):
        entries = {e.name: helps.resolved(e) for e in helps.page_entries(helps.help_page(alg.name()))}
        for definition in alg.parameterDefinitions():
            values = [v for v, _ in entries[definition.name()].values]
            if isinstance(definition, QgsProcessingParameterEnum):
                assert values == list(definition.options()), f"{alg.name()} {definition.name()}"
                example = f"(e.g. {definition.name()}={values[0]}; option numbers are refused)"
                assert example in definition.help() and f"; {values[-1]}: " in definition.help()
                checked += 1
            else:
                assert values == [], f"{alg.name()} {definition.name()} lists values but is no enumeration"
    assert checked == 31


def test_the_shared_entries_are_used_and_linked_to_their_sections(provider, helps):
    vocabulary = helps.VOCABULARY_PAGE.read_text()
    anchors = {re.sub(r"[^a-z0-9 -]", "", h.lower()).replace(" ", "-")
               for h in re.findall(r"^## (.+)$", vocabulary, re.M)}
    used = {d.name() for a in _algorithms(provider) for d in a.parameterDefinitions()}
    assert sorted(set(helps.vocabulary()) - used) == []
    links = 0
    for page in sorted(helps.ALGORITHM_PAGES.glob("*.md")):
        for name, anchor in re.findall(r"\[`([A-Z_0-9]+)`\]\(\.\./parameters\.md#([a-z-]+)\)", page.read_text()):
            assert name in helps.vocabulary() and anchor in anchors, (page.name, name, anchor)
            links += 1
    assert links > 100
    # the section a link names holds the entry
    for heading, body in re.findall(r"^## (.+?)\n(.*?)(?=^## |\Z)", vocabulary, re.M | re.S):
        anchor = re.sub(r"[^a-z0-9 -]", "", heading.lower()).replace(" ", "-")
        for page in sorted(helps.ALGORITHM_PAGES.glob("*.md")):
            for name in re.findall(rf"\[`([A-Z_0-9]+)`\]\(\.\./parameters\.md#{anchor}\)", page.read_text()):
                assert f"(`{name}`)" in body, (page.name, name, anchor)


def test_the_help_says_what_the_code_checks(provider, helps):
    presets = importlib.import_module(f"{PLUGIN}.simulation.presets")
    assert dict(helps.vocabulary()["PRESET"].values) == {n: p.description for n, p in presets.PRESETS.items()}
    for alg_id in ("simulatescene", "simulateblock"):
        assert f"({presets.MIN_CUT} or more;" in provider.algorithm(alg_id).parameterDefinition("IMAGE_SIZE").help()


def test_a_malformed_entry_is_refused_naming_its_page(helps, tmp_path):
    page = tmp_path / "broken.md"
    page.write_text("# Broken\n\nSummary.\n\n## Parameters\n\n- **Scene** (`SCENE`): The scene.\n"
                    "- **Points** (SAMPLES): How many.\n\n## Method\n\n- not an entry\n")
    with pytest.raises(ValueError, match=r"broken\.md: not a parameter entry .*Points"):
        helps.page_entries(page)
    page.write_text("# Fine\n\n## Parameters\n\n- **Scene** ([`SCENE`](../parameters.md#scenes-and-cameras)): Here"
                    "\n  only one.\n- **Mode** (`MODE`): How.\n  - `a`: first\n    line\n  - `b`: second\n\n"
                    "## Method\n\n- not an entry\n")
    scene, mode = helps.page_entries(page)
    assert (scene.name, scene.shared, scene.text) == ("SCENE", True, "Here only one.")
    assert helps.help_text(helps.resolved(scene)).endswith("(docs/rpc-scenes.md). Here only one.")
    assert mode.values == (("a", "first line"), ("b", "second"))
    assert helps.help_text(mode) == ("How. Values, by name (e.g. MODE=a; option numbers are refused): a: first line; "
                                     "b: second.")


def test_the_code_holds_no_help_text():
    """No ui module sets a parameter's help but the base class, from the docs (and the copy of a
    definition, which keeps its help)."""
    for path in sorted(set((REPO / "ui").rglob("*.py")) - {REPO / "ui" / "algorithms" / "base.py"}):
        calls = [n for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.Call)
                 and isinstance(n.func, ast.Attribute)]
        helps_set = [n.lineno for n in calls if n.func.attr == "setHelp"
                     and not (isinstance(n.args[0], ast.Call) and getattr(n.args[0].func, "attr", "") == "help")]
        assert helps_set == [], path
        assert [n.lineno for n in calls if n.func.attr == "add_parameter" and len(n.args) > 1] == [], path


def test_qgis_process_help_prints_the_page_entries(qgis_process, provider):
    done = qgis_process("help", "pushbroom:footprint")
    assert done.returncode == 0, done.stderr
    alg = provider.algorithm("footprint")
    for definition in alg.parameterDefinitions():
        assert definition.help() in " ".join(done.stdout.split()), definition.name()
    assert "How many intervals each edge of the image is divided into" in done.stdout


def test_the_dialog_help_lists_inputs_and_outputs_and_links_anchors_into_its_page(provider):
    alg = provider.algorithm("bundleadjust")
    page = (REPO / "docs" / "algorithms" / "bundleadjust.md").resolve()
    text = alg.shortHelpString()
    assert f'<a href="{page.as_uri()}#parameters-in-detail">Parameters in detail</a>' in text
    advanced = [d for d in alg.parameterDefinitions() if not d.isDestination()
                and d.flags() & QgsProcessingParameterDefinition.FlagAdvanced]
    assert f"(<code>INTERIOR</code>); {len(advanced)} more under <i>Advanced parameters</i>." in text
    assert len(advanced) > 15
    assert "<p><b>Outputs:</b> <b>Output scene</b> (<code>OUTPUT_SCENE</code>)," in text
