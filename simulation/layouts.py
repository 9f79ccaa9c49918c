"""Ready-made blocks of several scenes for :func:`simulation.block.simulate_block`: the layouts a
user of the Processing algorithm picks by name (tri-stereo, a stereo pair, two dates, neighbouring
strips, a tri-stereo with an RPC product of another date). Every member is the preset's first (or
only) camera, so that the scenes of a block are independent products of one sensor."""
from __future__ import annotations

from dataclasses import replace

from .blockmembers import BlockMember
from .presets import Preset

STEREO_PITCH = 15.0      # deg: a stereo pair, forward and backward (base-to-height ratio about 0.55)
TRI_STEREO_PITCH = 18.0  # deg: forward and backward of a tri-stereo with its nadir scene
OTHER_DATE_ROLL = 8.0    # deg: the other date's view across track
SIDE_LAP = 0.3           # share of the swath two neighbouring strips have in common
SECOND_DATE = "2011-03-02"


def one_camera(spec: Preset) -> Preset:
    """``spec`` with its first camera alone (named after the preset and camera when it had more)."""
    if len(spec.cameras) == 1:
        return spec
    return replace(spec, name=f"{spec.name}_{spec.cameras[0].name}", cameras=spec.cameras[:1])


def swath_km(spec: Preset) -> float:
    """Width (km) on the ground of the first camera's image at nadir."""
    cam = spec.cameras[0]
    return cam.cols * cam.pitch / cam.focal_length * spec.altitude / 1000.0


def tri_stereo(spec: Preset) -> list[BlockMember]:
    return [BlockMember("nad", spec), BlockMember("fwd", spec, view=(TRI_STEREO_PITCH, 0.0)),
            BlockMember("bwd", spec, view=(-TRI_STEREO_PITCH, 0.0))]


LAYOUTS = {
    "tristereo": tri_stereo,
    "stereo_pair": lambda spec: [BlockMember("fwd", spec, view=(STEREO_PITCH, 0.0)),
                                 BlockMember("bwd", spec, view=(-STEREO_PITCH, 0.0))],
    "two_dates": lambda spec: [BlockMember("date1", spec),
                               BlockMember("date2", spec, view=(0.0, OTHER_DATE_ROLL), date=SECOND_DATE)],
    "neighbouring_strips": lambda spec: [BlockMember("strip1", spec),
                                         BlockMember("strip2", spec, orbit_offset_km=(1 - SIDE_LAP) * swath_km(spec))],
    "tristereo_and_other_date": lambda spec: tri_stereo(spec) + [
        BlockMember("date2", spec, view=(0.0, OTHER_DATE_ROLL), date=SECOND_DATE, rpc=True)],
}
LAYOUT_MEANINGS = {
    "tristereo": f"nadir, forward and backward scenes of one pass (+-{TRI_STEREO_PITCH:g} deg)",
    "stereo_pair": f"forward and backward scenes of one pass (+-{STEREO_PITCH:g} deg)",
    "two_dates": f"a nadir scene and one of another date and radiometry, {OTHER_DATE_ROLL:g} deg across track",
    "neighbouring_strips": f"two strips of neighbouring orbits with {SIDE_LAP:.0%} side-lap",
    "tristereo_and_other_date": "the tri-stereo and a scene of another date delivered as an RPC product "
                                   "(<name>_RPC.TXT beside its image)",
    "region": "a region of RPC products over STRIPS strips of PRODUCTS_PER_STRIP products each, with SIDE_LAP and "
              "FORWARD_OVERLAP (rendered with RENDER)",
    "rpc_region": "a region of RPC products without images: TIES_PER_PRODUCT tie observations simulated directly "
                  "(a thousand products in minutes)",
}
# Layouts of a region (simulation.region): simulation.runs builds them from the region's own parameters.
REGION_LAYOUTS = ("region", "rpc_region")


def layout_members(layout: str, spec: Preset) -> list[BlockMember]:
    """The members of ``layout`` (a name of LAYOUTS) for the first camera of ``spec``."""
    return LAYOUTS[layout](one_camera(spec))
