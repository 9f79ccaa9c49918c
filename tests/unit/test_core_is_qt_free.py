"""core/ must run without QGIS: no module in it may import qgis or PyQt (design rule)."""
import ast
from pathlib import Path

CORE = Path(__file__).resolve().parents[2] / "core"
FORBIDDEN = ("qgis", "PyQt4", "PyQt5", "PyQt6", "sip")


def _imported_modules(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.append(node.module)
    return names


def test_core_does_not_import_qgis_or_qt():
    files = sorted(CORE.rglob("*.py"))
    assert len(files) >= 10  # the scan really sees the core
    offenders = [f"{f.relative_to(CORE.parent)}: import {m}" for f in files for m in _imported_modules(f)
                 if m.split(".")[0] in FORBIDDEN]
    assert not offenders, "core/ must not depend on QGIS/Qt:\n" + "\n".join(offenders)


def test_scanner_catches_both_import_forms(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import os\nfrom qgis.core import QgsPointXY\nif True:\n    import PyQt5.QtCore\n")
    assert [m for m in _imported_modules(bad) if m.split(".")[0] in FORBIDDEN] == ["qgis.core", "PyQt5.QtCore"]
