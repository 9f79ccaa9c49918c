"""What the readers of vendor XML metadata (:mod:`core.formats.dimap`, :mod:`core.formats.maxar`)
share: parsing the file, and lists of numbers in an element's text, with errors naming the file."""
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

