"""Where things are for the tests: the repository, its real test data, the plugin's package name and
the qgis_process binary."""
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
"""The repository root (the plugin folder; its name is not fixed: CI clones it anywhere)."""
TEST_DATA = REPO / "tests" / "data"
"""The real vendor test data (Pleiades DIMAP, WorldView-2 and WorldView-3 Maxar XML; tests/data/README.md)."""
PLUGIN = "pushbroom_adjust"
"""The name QGIS imports the plugin under (a symlink of that name -> REPO in a plugin folder)."""
QGIS_PROCESS = "/usr/bin/qgis_process.bin"
"""The qgis_process binary (Debian's /usr/bin/qgis_process wrapper is broken here)."""
