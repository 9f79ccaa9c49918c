"""Readers of vendor metadata into a SceneModel. Vendor conventions (1-based pixel
centres, scalar-last quaternions, time systems) are converted here and nowhere else."""
from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..errors import MetadataError


def parse_xml(path: str | Path) -> ElementTree.Element:
    """Parse an XML file, turning parser failures into a MetadataError naming the file."""
    try:
        return ElementTree.parse(str(path)).getroot()
    except ElementTree.ParseError as exc:
        raise MetadataError(f"{path}: not well-formed XML, truncated or corrupt ({exc})") from None


def parse_floats(text: str, src: str, where: str, min_count: int = 1) -> np.ndarray:
    """Whitespace-separated numbers of an XML element's text; MetadataError naming the file
    ``src`` and the element ``where`` when they are not numbers, not finite, or too few."""
    try:
        values = np.array([float(x) for x in text.split()])
    except ValueError:
        raise MetadataError(f"{src}: {where}: {text[:60]!r} is not a list of numbers") from None
    if values.size < min_count or not np.all(np.isfinite(values)):
        raise MetadataError(f"{src}: {where}: expected at least {min_count} finite numbers, got {values.size}")
    return values


def read_xml_scene(path: str | Path):
    """Dispatch an XML metadata file to the reader for its format."""
    root = parse_xml(path)
    if root.tag.endswith("Dimap_Document"):
        from .dimap import read_dimap
        return read_dimap(path, root)
    if root.tag == "isd" or root.find("IMD") is not None:
        from .maxar import read_maxar
        return read_maxar(path, root)
    raise MetadataError(f"{path}: unrecognised XML metadata (root element <{root.tag}>); "
                        "expected a DIMAP v2 document or Maxar/DigitalGlobe XML")
