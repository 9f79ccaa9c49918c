"""The repository imported as the plugin package ``pushbroom_adjust``, as QGIS imports it.

``core/``, ``simulation/`` and ``ui/`` reach each other by relative imports (``simulation`` imports
``..core``), so they work only inside one package. The repository folder's name is not fixed (CI
clones it anywhere): importing this module registers the folder under the plugin's name, so tests and
benchmarks write ``from pushbroom_adjust.core.model.sensor import SceneModel`` wherever the clone is.
"""
import importlib.util
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PLUGIN = "pushbroom_adjust"

if PLUGIN not in sys.modules:
    spec = importlib.util.spec_from_file_location(PLUGIN, REPO / "__init__.py", submodule_search_locations=[str(REPO)])
    package = importlib.util.module_from_spec(spec)
    sys.modules[PLUGIN] = package
    spec.loader.exec_module(package)
