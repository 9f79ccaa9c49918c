"""Everything that touches QGIS: the Processing provider and its algorithms (one per file)."""
from pathlib import Path

RESOURCES = Path(__file__).resolve().parents[1] / "resources"  # icons, output styles, graphical models
