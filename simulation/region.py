"""Region layouts: N products over a grid of strips (side by side across track, of one date each,
the dates cycled) and consecutive products along each strip, overlapping their neighbours by a
side-lap across track and a forward overlap along it, as a mapping agency's regional coverage is.

:func:`region_members` gives the layout as members of :func:`simulation.block.simulate_block`
(rigorous scenes or RPC products, rendered or not: small regions, e.g. 12 products in 3 strips of
a cut preset); :mod:`simulation.rpcregion` simulates large regions of RPC products without images.

An RPC product comes from a calibrated camera: its members keep the preset's trajectory errors
(what a vendor RPC misses by, a shift and a drift over a product: Fraser and Hanley 2003; Grodecki
and Dial 2003) without its lens and CCD errors (:data:`INTERIOR_ERRORS` zero), which bend a
product's lines by what an RPC's image-space correction (affine at most) cannot follow. Measured on
3 x 4 cuts of 600 x 600 px of TH-1 with the lens errors of seed 001 left in: the vendor RPC missed
the truth by up to 0.69 px beyond a drift and 0.28 px beyond an affine correction, all of it in the
column's square and cube (the distortion along the detector line), and the adjusted orthoimages of
neighbours disagreed by 0.09 to 0.65 px. Rigorous members keep them (self-calibration's work).

Frames: offsets in km on the ground, across track (> 0 to the right of the track) and along it
(> 0 forward); strips numbered from the left, products in imaging order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..core.errors import InputError
from .blockmembers import BlockMember
from .layouts import one_camera
from .presets import CAMERA_ERRORS, Preset

MIN_OVERLAP, MAX_OVERLAP = 0.02, 0.6   # shares: below, neighbours barely tie; above, a region wastes products
INTERIOR_ERRORS = (*CAMERA_ERRORS, "ccd_shift", "ccd_rotation")   # ErrorSettings fields of the lens and CCD
DATES = ("2012-03-01", "2012-04-12", "2012-05-20", "2012-07-03", "2012-09-15", "2012-10-28")


@dataclass(frozen=True)
class RegionLayout:
    """``strips`` strips side by side across track of ``products_per_strip`` consecutive products
    each; neighbouring strips share ``side_lap`` of a product's width, consecutive products of a
    strip ``forward_overlap`` of its length (shares, 0.02 to 0.6; agencies plan 0.1 to 0.3).
    ``dates``: strip k is acquired on date k mod dates (1 to 6, :data:`DATES`)."""
    strips: int = 3
    products_per_strip: int = 4
    side_lap: float = 0.2
    forward_overlap: float = 0.15
    dates: int = 1

    @property
    def n_products(self) -> int:
        return self.strips * self.products_per_strip

    def validate(self) -> None:
        """InputError naming the field at fault."""
        for name in ("strips", "products_per_strip", "dates"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InputError(f"{name} must be a whole number >= 1 (got {value!r})", parameter=name)
        if self.n_products < 2:
            raise InputError("a region needs at least two products (strips x products_per_strip)",
                             parameter="products_per_strip")
        if self.dates > len(DATES):
            raise InputError(f"dates must be 1 to {len(DATES)} (got {self.dates})", parameter="dates")
        for name in ("side_lap", "forward_overlap"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and MIN_OVERLAP <= value <= MAX_OVERLAP):
                raise InputError(f"{name} must be a share between {MIN_OVERLAP:g} and {MAX_OVERLAP:g} of a "
                                 f"product (got {value!r})", parameter=name)

    def names(self) -> list[str]:
        """Product names s<strip>p<product>, numbered from 1 and zero-padded, strip by strip."""
        ws, wp = len(str(self.strips)), len(str(self.products_per_strip))
        return [f"s{i + 1:0{ws}d}p{j + 1:0{wp}d}" for i in range(self.strips) for j in range(self.products_per_strip)]

    def offsets_km(self, width_km: float, length_km: float) -> list[tuple[float, float]]:
        """(across, along) offset (km) of each product's centre from the region's centre, in the
        order of :meth:`names`, for products ``width_km`` wide and ``length_km`` long."""
        across, along = (1.0 - self.side_lap) * width_km, (1.0 - self.forward_overlap) * length_km
        mid_s, mid_p = (self.strips - 1) / 2.0, (self.products_per_strip - 1) / 2.0
        return [((i - mid_s) * across, (j - mid_p) * along)
                for i in range(self.strips) for j in range(self.products_per_strip)]

    def date(self, strip: int) -> str:
        """The date label of strip ``strip`` (0-based)."""
        return DATES[strip % self.dates]


def footprint_km(spec: Preset) -> tuple[float, float]:
    """(width, length) km on the ground of the first camera's image of one scene at nadir."""
    cam = spec.cameras[0]
    gsd_km = cam.pitch / cam.focal_length * spec.altitude / 1000.0
    return cam.cols * gsd_km, spec.scene_rows * gsd_km


def region_members(layout: RegionLayout, spec: Preset, rpc: bool = True,
                   all_cameras: bool = False) -> list[BlockMember]:
    """The products of ``layout`` as block members of the first camera of ``spec`` (a preset, e.g.
    a :func:`simulation.presets.cut_preset`), each at nadir with its strip's date; ``rpc``: delivered
    as RPC products, of the calibrated camera (the preset's INTERIOR_ERRORS zero: see the module
    docstring); ``all_cameras``: every camera of ``spec`` (three-line scenes; the layout is still laid
    out by the first camera's footprint). InputError naming the layout field at fault."""
    layout.validate()
    spec = spec if all_cameras else one_camera(spec)
    if rpc:
        spec = replace(spec, errors=replace(spec.errors, **{name: 0.0 for name in INTERIOR_ERRORS}))
    width, length = footprint_km(spec)
    names = layout.names()
    if not math.isfinite(width * length) or width <= 0 or length <= 0:
        raise InputError(f"preset {spec.name} has no ground footprint", parameter="preset")
    return [BlockMember(name, spec, orbit_offset_km=across, along_track_km=along,
                        date=layout.date(k // layout.products_per_strip), rpc=rpc)
            for k, (name, (across, along)) in enumerate(zip(names, layout.offsets_km(width, length)))]
