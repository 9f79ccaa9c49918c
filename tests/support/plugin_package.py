"""The repository imported as the plugin package ``pushbroom_adjust``, as QGIS imports it.

``core/``, ``simulation/`` and ``ui/`` reach each other by relative imports (``simulation`` imports
``..core``), so they work only inside one package. The repository folder's name is not fixed (CI
clones it anywhere): importing this module puts a folder holding a link ``pushbroom_adjust`` -> the
repository first on ``sys.path`` and on ``PYTHONPATH`` (so that worker processes, e.g. of a Dask
cluster, import the same package), and tests and benchmarks write
``from pushbroom_adjust.core.model.sensor import SceneModel`` wherever the clone is.
"""
import atexit
import os
import shutil
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PLUGIN = "pushbroom_adjust"

if PLUGIN not in sys.modules:
    folder = tempfile.mkdtemp(prefix="pushbroom-plugins-")
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    (Path(folder) / PLUGIN).symlink_to(REPO, target_is_directory=True)
    sys.path.insert(0, folder)
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, (folder, os.environ.get("PYTHONPATH"))))
