"""RPC test scenes from the real vendor models (tests/data): the Pleiades Global_RFM and the
WorldView-2 RPB, optionally scaled to a smaller image (the same ground, coarser pixels), written
as the files users hold (an image with RPC tags, ``_RPC.TXT``, ``.RPB``)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from osgeo import gdal

from pushbroom_adjust.core.formats.dimaprfm import read_dimap_rfm
from pushbroom_adjust.core.formats.maxar import read_maxar_rpc
from pushbroom_adjust.core.model.rpc import RpcModel
from pushbroom_adjust.core.formats.rpcfiles import set_geotiff_rpc, write_rpc
from pushbroom_adjust.core.model.rpcscene import size_from_rpc

PLEIADES = "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"
PLEIADES_DEM = "pleiades/MNT_P1BP--2018122638935449CP.tif"  # ellipsoidal heights
WORLDVIEW2 = "worldview2/wv_mvp_1.xml"


def pleiades_rpc(data: Path) -> RpcModel:
    """The vendor inverse RFM of the Pleiades scene (1-based model coordinates)."""
    return read_dimap_rfm(data / PLEIADES)[0]


def worldview2_rpc(data: Path) -> RpcModel:
    return read_maxar_rpc(data / WORLDVIEW2)


def scaled(rpc: RpcModel, factor: float) -> RpcModel:
    """The RPC of the image ``factor`` times smaller each way (origin 0): model pixel p of the
    original becomes (p - origin + 0.5) / factor - 0.5."""
    def off(v):
        return (v - rpc.origin + 0.5) / factor - 0.5
    return replace(rpc, line_off=off(rpc.line_off), samp_off=off(rpc.samp_off), line_scale=rpc.line_scale / factor,
                   samp_scale=rpc.samp_scale / factor, origin=0.0)


def write_image(path: Path, cols: int, rows: int, rpc: RpcModel | None = None) -> Path:
    """A tiled uint8 GeoTIFF of a smooth pattern with sharp edges (a checkerboard of 32 px cells
    plus a gradient), with the RPC in its tags when given."""
    ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte,
                                              ["TILED=YES", "COMPRESS=DEFLATE"])
    for r0 in range(0, rows, 1024):
        n = min(1024, rows - r0)
        i, j = np.mgrid[r0:r0 + n, 0:cols]
        block = ((i // 32 + j // 32) % 2) * 120 + (i * 7 + j * 3) % 100 + 20
        ds.GetRasterBand(1).WriteArray(block.astype(np.uint8), 0, r0)
    ds = None
    if rpc is not None:
        set_geotiff_rpc(rpc, path)
    return path


def rpc_files(folder: Path, rpc: RpcModel, name: str = "scene") -> dict:
    """{'txt': <name>_RPC.TXT, 'rpb': <name>.RPB (beside no image), 'tif': <name>.tif with RPC tags}."""
    cols, rows = size_from_rpc(rpc)
    txt = write_rpc(rpc, folder / f"{name}_RPC.TXT")
    rpb = write_rpc(rpc, folder / f"{name}_b.RPB")
    tif = write_image(folder / f"{name}.tif", cols, rows, rpc)
    return {"txt": txt, "rpb": rpb, "tif": tif, "cols": cols, "rows": rows}


def padded_dem(data: Path, path: Path, pad: int = 3) -> Path:
    """The Pleiades DEM (ellipsoidal heights) extended by ``pad`` cells of its edge values on
    every side: the vendor DEM ends a few hundred metres short of bilinear coverage of the
    scene's east edge."""
    src = gdal.Open(str(data / PLEIADES_DEM))
    heights = np.pad(src.GetRasterBand(1).ReadAsArray().astype(np.float32), pad, mode="edge")
    x0, dx, _, y0, _, dy = src.GetGeoTransform()
    ds = gdal.GetDriverByName("GTiff").Create(str(path), heights.shape[1], heights.shape[0], 1, gdal.GDT_Float32)
    ds.SetGeoTransform((x0 - pad * dx, dx, 0.0, y0 - pad * dy, 0.0, dy))
    ds.SetProjection(src.GetProjection())
    ds.GetRasterBand(1).WriteArray(heights)
    ds = None
    return path
