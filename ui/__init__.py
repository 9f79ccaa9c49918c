"""Everything that touches QGIS: the Processing provider and its algorithms (one per file)."""
