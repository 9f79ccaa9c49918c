"""The checks every shipped graphical model (resources/models/*.model3) passes."""
from pathlib import Path

from qgis.core import QgsApplication, QgsProcessingModelAlgorithm


def assert_shipped_model(path: Path, model_id: str, steps: list[str], help_text: str) -> None:
    """The model file loads and is valid, runs ``steps`` (algorithm ids, top to bottom in the
    modeler), and the provider lists it under Workflows with ``help_text`` in its help."""
    model = QgsProcessingModelAlgorithm()
    assert model.fromFile(str(path))
    ok, problems = model.validate()
    assert ok, problems
    assert [c.algorithmId() for c in sorted(model.childAlgorithms().values(), key=lambda c: c.position().y())] == steps
    alg = QgsApplication.processingRegistry().algorithmById(model_id)
    assert alg is not None and alg.group() == "Workflows" and help_text in alg.shortHelpString()
