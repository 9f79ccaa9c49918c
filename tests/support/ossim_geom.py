"""OSSIM keyword-list RPCs (``.geom``, ``type: ossimRpcModel`` or ``ossimPleiadesModel``) of the real crops in
tests/data (pleiades_gizeh, pleiades_ventoux): the file's numbers, as GDAL 'RPC' metadata, and the RPC of a
crop of the product written with the full product's offsets (the crop's origin folded into the numerators).

The .geom's image coordinates are OSSIM's, 0 at the first pixel's centre: the same as GDAL's RPC metadata, so
its numbers go into GDAL's keys unchanged."""
from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from pushbroom_adjust.core.model.rpc import RpcModel

# GDAL's RPC metadata key of each .geom key of the offsets and scales
SCALARS = {"LINE_OFF": "line_off", "SAMP_OFF": "samp_off", "LAT_OFF": "lat_off", "LONG_OFF": "long_off",
           "HEIGHT_OFF": "height_off", "LINE_SCALE": "line_scale", "SAMP_SCALE": "samp_scale",
           "LAT_SCALE": "lat_scale", "LONG_SCALE": "long_scale", "HEIGHT_SCALE": "height_scale"}
LISTS = {"LINE_NUM_COEFF": "line_num", "LINE_DEN_COEFF": "line_den", "SAMP_NUM_COEFF": "samp_num",
         "SAMP_DEN_COEFF": "samp_den"}


def read_geom(path: Path) -> dict:
    """The keyword list of a .geom file: {key: value text}."""
    return dict(re.match(r"\s*([^:]+):\s*(.*)", line).groups() for line in Path(path).read_text().splitlines()
                if ":" in line)


def coefficients(geom: dict, name: str) -> np.ndarray:
    """The 20 coefficients (20,) of one list of a .geom ('line_num', 'line_den', 'samp_num', 'samp_den')."""
    return np.array([float(geom[f"{name}_coeff_{i:02d}"]) for i in range(20)])


def gdal_rpc_metadata(geom: dict) -> dict:
    """GDAL's 'RPC' metadata domain of a .geom's RPC (the file's own numbers, as text)."""
    md = {key: geom[name] for key, name in SCALARS.items()}
    md.update({key: " ".join(geom[f"{name}_coeff_{i:02d}"] for i in range(20)) for key, name in LISTS.items()})
    return md


def geom_rpc(geom: dict) -> RpcModel:
    """The .geom's RPC as a model (origin 0, as GDAL's)."""
    return RpcModel(*(coefficients(geom, name) for name in LISTS.values()),
                    lon_off=float(geom["long_off"]), lon_scale=float(geom["long_scale"]),
                    lat_off=float(geom["lat_off"]), lat_scale=float(geom["lat_scale"]),
                    height_off=float(geom["height_off"]), height_scale=float(geom["height_scale"]),
                    line_off=float(geom["line_off"]), line_scale=float(geom["line_scale"]),
                    samp_off=float(geom["samp_off"]), samp_scale=float(geom["samp_scale"]))


def folded_crop_rpc(rpc: RpcModel, x0: float, y0: float) -> RpcModel:
    """The RPC of the crop whose first pixel is pixel (x0, y0) of ``rpc``'s image, written with the full
    product's offsets and scales: line' = LINE_SCALE num'/den + LINE_OFF = line - y0 with num' = num -
    (y0 / LINE_SCALE) den, the same for samples (exact to rounding)."""
    return replace(rpc, line_num=rpc.line_num - (y0 / rpc.line_scale) * rpc.line_den,
                   samp_num=rpc.samp_num - (x0 / rpc.samp_scale) * rpc.samp_den)
