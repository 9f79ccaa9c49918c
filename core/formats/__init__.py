"""Files that hold a scene: scene JSON and its schema, DIMAP, Maxar XML, RPC text/RPB/DIMAP RPC.

:func:`load_scene` is the door: it reads any of them into a model (:class:`core.model.sensor.SceneModel`
or :class:`core.model.rpcscene.RpcScene`). Vendor conventions (1-based pixel centres, scalar-last
quaternions, time systems) are converted by the readers of this package and nowhere else. A rigorous
vendor product is checked against the RPC its vendor ships with it (:mod:`core.formats.vendorcheck`)
once it has passed the checks of every scene (:mod:`core.formats.schema`).
"""
from __future__ import annotations

import json
from pathlib import Path

from ..errors import MetadataError
from ..model.rpcscene import RpcScene
from ..model.sensor import SceneModel
from .dimap import read_dimap
from .maxar import read_maxar
from .rpcfiles import is_rpc_text, read_dimap_rpc, read_rpc_image, read_rpc_text
from .scene_json import scene_from_dict, validate_scene
from .schema import check_scene_model
from .vendorcheck import VendorRpc, check_vendor_rpc
from .vendor_xml import parse_xml

UTF8_BOM = b"\xef\xbb\xbf"  # written by some editors (Notepad); JSON and XML both allow it


def read_xml_scene(path: str | Path) -> tuple[SceneModel, VendorRpc | None]:
    """The scene of an XML metadata file, by the reader for its format (DIMAP v2 or Maxar), and
    the RPC the product ships to check it against (None when it has none)."""
    root = parse_xml(path)
    if root.tag.endswith("Dimap_Document"):
        return read_dimap(path, root)
    if root.tag == "isd" or root.find("IMD") is not None:
        return read_maxar(path, root)
    raise MetadataError(f"{path}: unrecognised XML metadata (root element <{root.tag}>); "
                        "expected a DIMAP v2 document or Maxar/DigitalGlobe XML")


def load_scene(path: str | Path) -> SceneModel | RpcScene:
    """Read any supported scene: scene JSON, Pleiades/SPOT DIMAP v2, Maxar/DigitalGlobe XML, and
    RPC sources (:mod:`core.formats.rpcfiles`): an RPC scene JSON, ``_RPC.TXT``, ``.RPB``, DIMAP
    ``RPC_*.XML``, or an image with RPC metadata GDAL reads."""
    path = Path(path)
    if not path.is_file():
        raise MetadataError(f"{path}: no such file")
    with path.open("rb") as f:
        head = f.read(4096).removeprefix(UTF8_BOM).lstrip()
    if head.startswith((b"{", b"[")):
        try:
            d = json.loads(path.read_text(encoding="utf-8-sig"))
            scene = scene_from_dict(d, str(path))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise MetadataError(f"{path}: invalid JSON ({exc})") from None
        except RecursionError:
            raise MetadataError(f"{path}: JSON nested far more deeply than a scene file (a few levels); not a "
                                "scene JSON") from None
        if isinstance(scene, SceneModel):
            check_scene_model(scene, str(path))
    elif head.startswith(b"<") and path.name.upper().startswith("RPC_"):
        scene = read_dimap_rpc(path, parse_xml(path))
    elif head.startswith(b"<"):
        scene, vendor = read_xml_scene(path)
        validate_scene(scene, str(path))
        if vendor is not None:
            check_vendor_rpc(scene, vendor, str(path))
    elif is_rpc_text(path, head):
        scene = read_rpc_text(path)
    else:
        scene = read_rpc_image(path)
        if scene is None:
            raise MetadataError(f"{path}: neither scene JSON nor XML metadata (DIMAP v2 or Maxar), nor an RPC file "
                                "(_RPC.TXT, .RPB) or an image with RPC metadata")
    scene.info.setdefault("source", str(path))
    return scene
