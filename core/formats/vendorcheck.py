"""A rigorous vendor product checked against the RPC its vendor ships with it, on load.

Every reader of a rigorous product (:mod:`core.formats.maxar`: the RPB section of the XML or an
``.RPB`` beside it; :mod:`core.formats.dimap`: the ``Global_RFM`` of the DIMAP document or the
product's ``RPC_*.XML``) returns, with the scene, the product's own RPC (:class:`VendorRpc`).
:func:`check_vendor_rpc` compares the two over the image and the RPC's height range: GRID x GRID
image points from the first to the last pixel centre, at the lowest, middle and highest height of
the RPC (its height offset -+ scale), are put on the ground by the rigorous model and back into
the image by the RPC. The distance (px) between the two image positions is the figure.

The bound is on the RMS: MAX_RMS_PX (1 px) for the vendor's own RPC. The largest distance is
reported, not bounded: a cubic RPC cannot follow attitude motion, which leaves up to 1.8 px at
1.0 px RMS in a sound WorldView-3 product, while every reader error seen is hundreds to tens of
thousands of pixels (a GeoEye-1 product's detector rotation read in degrees instead of radians:
10,577 px RMS; the WorldView-1 product's one degree off: 366 px). An RPC refitted by another tool
to a model without velocity aberration and refraction (the Ames Stereo Pipeline's dg_mosaic,
:mod:`core.formats.maxar`) is compared with the model it was fitted to (both corrections off) and
held to REFIT_MAX_RMS_PX (3 px): its cubic leaves 1.0 px RMS of attitude motion. Beyond the bound
the product is refused (MetadataError naming both models and the figure); below, the figure is
logged and kept in ``scene.info["rpc_check"]``.

Cost: 3 GRID^2 = 363 points through image_to_ground and the RPC, 0.01-0.03 s per scene.
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from ..errors import MetadataError
from ..geodesy import ecef_to_geodetic
from ..model.rpc import RpcModel
from ..model.sensor import SceneModel

log = logging.getLogger(__name__)

GRID = 11               # image points per side of the checked grid
MAX_RMS_PX = 1.0        # bound on the RMS against the vendor's own RPC
REFIT_MAX_RMS_PX = 3.0  # bound against an RPC refitted by another tool to the model without corrections


@dataclass
class VendorRpc:
    """The RPC shipped in a rigorous product. ``source`` names it (file, and section when it is
    part of the metadata file); ``refit_without_corrections``: made by another tool than the
    vendor, fitted to the model without velocity aberration and refraction; ``assumed``: what the
    reader assumed about the product (named in a refusal, e.g. an angle's unit)."""
    rpc: RpcModel
    source: str
    refit_without_corrections: bool = False
    assumed: tuple[str, ...] = ()


def check_vendor_rpc(scene: SceneModel, vendor: VendorRpc, source: str) -> dict:
    """Compare the rigorous scene (its first camera, read from ``source``) with the product's RPC
    (see the module docstring). Returns the figures, also kept in ``scene.info["rpc_check"]`` and
    logged; MetadataError naming both models and the figure when the RMS exceeds the bound, or
    when grid points have no position in one of the models."""
    model = dataclasses.replace(scene, aberration=False, refraction=False, _guess={}) \
        if vendor.refit_without_corrections else scene
    bound = REFIT_MAX_RMS_PX if vendor.refit_without_corrections else MAX_RMS_PX
    col, row, height = check_points(scene.cameras[0].cols, scene.cameras[0].rows, vendor.rpc)
    lon, lat, _ = ecef_to_geodetic(model.image_to_ground(col, row, height))
    with np.errstate(invalid="ignore", divide="ignore"):
        c, r = vendor.rpc.ground_to_image(lon, lat, height)
    distance = np.hypot(c - col, r - row)
    what = (f"{source}: the rigorous model{' without velocity aberration and refraction' if model is not scene else ''}"
            f" against {vendor.source}")
    assumed = f" (assumed: {'; '.join(vendor.assumed)})" if vendor.assumed else ""
    lost = ~np.isfinite(distance)
    if lost.any():
        raise MetadataError(f"{what}: {int(lost.sum())} of {distance.size} image points of the check have no "
                            f"position in one of the two models: the rigorous model does not describe this "
                            f"product{assumed}")
    rms, worst = float(np.sqrt(np.mean(distance ** 2))), float(distance.max())
    figures = {"rpc": vendor.source, "rms_px": rms, "max_px": worst, "bound_rms_px": bound,
               "points": f"{GRID} x {GRID} image points x 3 heights",
               "heights_m": [float(height.min()), float(height.max())],
               "corrections": "off (the model the RPC was fitted to)" if model is not scene else "as read"}
    summary = f"{what}: {rms:.3f} px RMS, {worst:.3f} px max over {figures['points']}"
    if rms > bound:
        raise MetadataError(f"{summary}, beyond the {bound:g} px RMS the vendor's own RPC meets: the rigorous model "
                            f"is read wrongly or the product is inconsistent{assumed}")
    figures["summary"] = summary
    scene.info["rpc_check"] = figures
    log.info("%s", summary)
    return figures


def check_points(cols: int, rows: int, rpc: RpcModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """GDAL (col, row) and heights (m), each (3 GRID^2,): GRID x GRID image points from the first to
    the last pixel centre, at the lowest, middle and highest height of the RPC (offset -+ scale)."""
    c, r = (a.ravel() for a in np.meshgrid(np.linspace(0.5, cols - 0.5, GRID), np.linspace(0.5, rows - 0.5, GRID)))
    low, high = rpc.height_off - abs(rpc.height_scale), rpc.height_off + abs(rpc.height_scale)
    heights = np.repeat([low, 0.5 * (low + high), high], c.size)
    return np.tile(c, 3), np.tile(r, 3), heights
