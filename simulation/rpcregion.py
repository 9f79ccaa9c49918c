"""Regions of RPC products without images: hundreds to thousands of products simulated in
minutes, their tie observations simulated directly, with the truth known exactly.

The products are those of a :class:`simulation.region.RegionLayout`. One RPC00B template is fitted
(:func:`core.products.rpcfit.fit_rpc`) to the true rigorous model of one nadir scene of the
preset's first camera (ZY-3's nadir line by default: 2.1 m, 51 km swath) over the terrain's heights;
each product's RPC is the template moved to its centre (its longitude and latitude offsets; its
longitude scale divided by the cosine of its latitude's ratio to the template's, so that it covers
the same metres on the ground): an exact rational model, not a fit, so that 1,000 products cost
no 1,000 rigorous fits. Measured: the template's fit 0.12 s, its check 5e-6 px RMS.

The vendor's error is an image-space bias of the kind Grodecki & Dial (2003) correct: each
product's true model is its RPC file followed by the correction (:class:`core.model.rpcscene.RpcScene`)
    col' = col + a0 + a2 * row,    row' = row + b0 + b2 * row
with a shift (a0, b0) of ``bias_m`` metres (drawn uniformly between its two ends, in a uniform
direction; real vendor RPCs of ZY-3 and GF-1 are good to 5-20 m) and a drift (a2, b2) displacing
the last row by up to ``drift_m`` metres per axis. The truth is the true scene JSON of each product
(the RPC and its correction): exact, whatever the adjustment estimates.

Tie and check points lie on the written DEM (its bilinear surface, EGM96 converted to
ellipsoidal heights): each point projected through every true model whose image holds it,
``image_noise`` px of Gaussian noise added. Tie points are drawn uniformly over the union of the
footprints, those seen by two products or more kept, then thinned to ``ties_per_product`` tie
observations per product on average; check points uniformly, seen by one product or more.

Files in the folder: ``products/<name>_RPC.TXT`` (what the plugin reads as each product: its image
size assumed from the RPC's line and sample range, as no image is beside it); ``truth/<name>.json``
(the true RPC scene); ``dem.tif`` (EGM96 geoid heights); ``tie_points.csv`` (columns of
:data:`simulation.measurements.TIE_COLUMNS`: ``camera`` and ``scene`` the product's name);
``gcps.csv`` (ground points with their true coordinates, a share of them check points, the others
control; with ``corner_gcps`` the 4 nearest the region's corners control;
:data:`simulation.measurements.GCP_COLUMNS`); ``region.json`` (the layout, the settings, each
product's strip, date, files and true correction).

Frames: (lon, lat) degrees, ellipsoidal heights (m), image coordinates GDAL (col, row) px.
"""
from __future__ import annotations

import json
import logging
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..core.dem import Dem, to_ellipsoidal
from ..core.errors import Cancelled, InputError
from ..core.files import atomic_outputs, write_text
from ..core.formats.rpcfiles import write_rpc
from ..core.formats.scene_json import save_scene
from ..core.model.rpc import RpcModel
from ..core.model.rpcscene import RpcCamera, RpcScene
from ..core.products.rpcfit import fit_rpc
from .geometry import build_scenes
from .layouts import one_camera
from .measurements import GCP_COLUMNS, TIE_COLUMNS
from .memory import refuse_beyond_memory
from .presets import PRESETS, ErrorSettings, Preset
from .region import RegionLayout
from .regionpoints import boxes, draw_points, ids, neighbours, write_columns
from .simulator import check_folder, new_folder
from .terrain import write_dem
from .texture import M_PER_DEG_LAT, M_PER_DEG_LON

log = logging.getLogger(__name__)

MANIFEST = "region.json"
HEIGHT_MARGIN = 150.0   # m around the terrain's heights (geoid undulation across a region included)
# Bytes held per tie observation (arrays while drawing, then the CSV's text) and per candidate point
# drawn (positions, heights, visibility), about three candidates per observation: 930 bytes per
# observation in all. Measured: 100 products x 2,000 observations, 400 MB peak with the ~200 MB of
# the interpreter and its libraries (tests/bench/bench_region.py).
OBSERVATION_BYTES, CANDIDATE_BYTES = 450, 160


@dataclass
class RegionSettings:
    """What a region of RPC products holds. ties_per_product: tie observations per product on
    average; n_gcps: ground points with their true coordinates, uniform over the region, each seen
    by one product or more (None: 4 per product); check_fraction: the share of them made check
    points, drawn at random, the others control; corner_gcps: the 4 nearest the region's corners
    control whatever the draw; image_noise (px): of every
    measurement; bias_m: (least, largest) shift of a vendor RPC (m); drift_m: the largest
    displacement of a product's last row by the drift (m, per axis). forward_ties: tie points
    seen only by consecutive products of one strip too (False: only points seen by two strips or
    more). Those products see them along the same rays (one pass, one line of detectors): their
    heights are undetermined by the ties (zero base), held only by a height reference."""
    ties_per_product: int = 2000
    n_gcps: int | None = None
    check_fraction: float = 1.0
    corner_gcps: bool = False
    image_noise: float = 0.3
    bias_m: tuple[float, float] = (5.0, 20.0)
    drift_m: float = 2.0
    forward_ties: bool = True

    def gcps(self, n_products: int) -> int:
        """The ground points with coordinates of a region of ``n_products``."""
        return 4 * n_products if self.n_gcps is None else int(self.n_gcps)

    def validate(self) -> None:
        for name in ("ties_per_product", "n_gcps"):
            value = getattr(self, name)
            if value is None and name == "n_gcps":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise InputError(f"{name} must be a whole number >= 0 (got {value!r})", parameter=name)
        if not (math.isfinite(self.check_fraction) and 0 <= self.check_fraction <= 1):
            raise InputError(f"check_fraction must be between 0 and 1 (got {self.check_fraction!r})",
                             parameter="check_fraction")
        if not (math.isfinite(self.image_noise) and 0 <= self.image_noise <= 10):
            raise InputError(f"image_noise must be 0 to 10 px (got {self.image_noise!r})", parameter="image_noise")
        lo, hi = self.bias_m
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo <= hi <= 1000):
            raise InputError(f"bias_m must be (least, largest) metres, 0 <= least <= largest <= 1000 (got "
                             f"{self.bias_m!r})", parameter="bias_m")
        if not (math.isfinite(self.drift_m) and 0 <= self.drift_m <= 1000):
            raise InputError(f"drift_m must be 0 to 1000 m (got {self.drift_m!r})", parameter="drift_m")


@dataclass
class RegionResult:
    """The files of :func:`simulate_region`: products {name: RPC file}, truth {name: true scene JSON}."""
    folder: Path
    manifest: Path
    dem: Path
    gcps: Path
    tie_points: Path
    products: dict = field(default_factory=dict)
    truth: dict = field(default_factory=dict)


def region_memory(layout: RegionLayout, settings: RegionSettings) -> float:
    """Bytes :func:`simulate_region` holds at its peak (see OBSERVATION_BYTES, CANDIDATE_BYTES): the
    observations, and the candidate points drawn for them (about three per observation kept)."""
    observations = layout.n_products * settings.ties_per_product + 3 * settings.gcps(layout.n_products)
    return float(observations * (OBSERVATION_BYTES + 3 * CANDIDATE_BYTES))


def output_names(layout: RegionLayout) -> list[str]:
    """Paths (relative to the folder) of the files :func:`simulate_region` writes."""
    return (["dem.tif", "gcps.csv", "tie_points.csv", MANIFEST]
            + [f"products/{n}_RPC.TXT" for n in layout.names()] + [f"truth/{n}.json" for n in layout.names()])


def region_files(folder: Path) -> set[str]:
    """Paths an earlier region simulation wrote into ``folder`` (from its region.json; empty without)."""
    try:
        listed = json.loads((folder / MANIFEST).read_text())["files"]["all"]
    except (OSError, ValueError, KeyError, TypeError):
        return set()
    return set(listed) | {MANIFEST} if isinstance(listed, list) else set()


def simulate_region(layout: RegionLayout, folder, preset: str | Preset = "zy3_tlc", seed: int = 0,
                    settings: RegionSettings | None = None,
                    progress: Callable[[float, str | None], None] | None = None,
                    is_cancelled: Callable[[], bool] | None = None) -> RegionResult:
    """Simulate the RPC products of ``layout`` (no images) into ``folder`` (created), of the first
    camera of ``preset`` (a name of PRESETS or a Preset); see the module docstring. Refused before
    any work when this machine's memory cannot hold it (InputError naming 'products_per_strip',
    with the estimate). Every file or none; files already in the folder are replaced only when an
    earlier region simulation wrote them."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be a whole number >= 0 (got {seed!r})", parameter="seed")
    layout.validate()
    settings = settings or RegionSettings()
    settings.validate()
    if not isinstance(preset, Preset) and preset not in PRESETS:
        raise InputError(f"unknown preset {preset!r} (choose one of {', '.join(PRESETS)})", parameter="preset")
    refuse_beyond_memory(region_memory(layout, settings), "products_per_strip",
                         f"a region of {layout.n_products} products x {settings.ties_per_product} tie observations "
                         f"(about {OBSERVATION_BYTES + 3 * CANDIDATE_BYTES} bytes each)")
    folder = Path(folder)
    check_folder(folder, output_names(layout), MANIFEST, region_files)
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)

    def step(fraction: float, message: str | None) -> None:
        if cancelled():
            raise Cancelled("simulation cancelled by the user")
        report(fraction, message)
        if message:
            log.info(message)

    spec = one_camera(preset if isinstance(preset, Preset) else PRESETS[preset])
    with new_folder(folder), new_folder(folder / "products"), new_folder(folder / "truth"):
        return _simulate(layout, folder, spec, int(seed), settings, step)


def _template(spec: Preset, seed: int) -> tuple[RpcModel, dict, tuple[int, int], tuple[float, float]]:
    """(the RPC fitted to the true model of one nadir scene of ``spec`` at its centre, the fit report,
    the image (cols, rows), the height range (m, ellipsoidal) it was fitted over)."""
    lon, lat = spec.centre
    geoid = float(to_ellipsoidal(lon, lat, 0.0, "geoid"))
    heights = (200.0 + geoid - HEIGHT_MARGIN, 200.0 + spec.relief + geoid + HEIGHT_MARGIN)
    true = build_scenes(spec, 1, ErrorSettings(), np.random.default_rng([seed, 11])).true
    rpc, fit = fit_rpc(true, 0, heights)
    cam = true.cameras[0]
    return rpc, fit, (cam.cols, cam.rows), heights


def _footprint_axes(rpc: RpcModel, size: tuple[int, int], h: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(unit across (east, north), unit along, width m, length m) of the image's footprint at height h."""
    cols, rows = size
    lon, lat = rpc.image_to_ground(np.array([0.0, cols, cols / 2, cols / 2]),
                                   np.array([rows / 2, rows / 2, 0.0, rows]), h)
    scale = np.array([M_PER_DEG_LON * math.cos(math.radians(float(lat.mean()))), M_PER_DEG_LAT])
    across = np.array([lon[1] - lon[0], lat[1] - lat[0]]) * scale
    along = np.array([lon[3] - lon[2], lat[3] - lat[2]]) * scale
    return (across / np.linalg.norm(across), along / np.linalg.norm(along), float(np.linalg.norm(across)),
            float(np.linalg.norm(along)))


def product_rpcs(layout: RegionLayout, template: RpcModel, size: tuple[int, int], h: float) -> list[RpcModel]:
    """Each product's RPC: ``template`` moved by the product's offset (:meth:`RegionLayout.offsets_km`
    along the template footprint's axes at height h), metres to degrees at the product's own
    latitude, its longitude scale widened by 1 / cos(latitude) against the template's."""
    across, along, width, length = _footprint_axes(template, size, h)
    lat0 = template.lat_off
    out = []
    for a, b in layout.offsets_km(width / 1e3, length / 1e3):
        east, north = (a * across + b * along) * 1e3
        lat = lat0 + north / M_PER_DEG_LAT
        ratio = math.cos(math.radians(lat0)) / math.cos(math.radians(lat))
        lon = template.lon_off + east / (M_PER_DEG_LON * math.cos(math.radians(lat)))
        out.append(replace(template, lon_off=lon, lat_off=lat, lon_scale=template.lon_scale * ratio))
    return out


def true_corrections(n: int, settings: RegionSettings, gsd: float, rows: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 2, 3) corrections [[a0, a1, a2], [b0, b1, b2]] (px, px/px) of the products' true models:
    shift of U(bias_m) metres in a uniform direction, drift of U(-drift_m, drift_m) metres per axis
    at the last row; gsd (m/px), rows: the image's."""
    size = rng.uniform(*settings.bias_m, n) / gsd
    angle = rng.uniform(0.0, 2 * math.pi, n)
    drift = rng.uniform(-settings.drift_m, settings.drift_m, (n, 2)) / gsd / rows
    out = np.zeros((n, 2, 3))
    out[:, 0, 0], out[:, 1, 0] = size * np.cos(angle), size * np.sin(angle)
    out[:, 0, 2], out[:, 1, 2] = drift[:, 0], drift[:, 1]
    return out


def _simulate(layout: RegionLayout, folder: Path, spec: Preset, seed: int, settings: RegionSettings,
              step) -> RegionResult:
    """:func:`simulate_region` once its arguments are checked and the folders exist."""
    names = layout.names()
    step(0.01, f"fitting the RPC template of {spec.name}")
    template, fit, size, heights = _template(spec, seed)
    rpcs = product_rpcs(layout, template, size, sum(heights) / 2)
    _, _, width, _ = _footprint_axes(template, size, sum(heights) / 2)
    rng = np.random.default_rng([seed, 12])
    corrections = true_corrections(len(names), settings, width / size[0], size[1], rng)
    truth = {n: RpcScene(r, RpcCamera(n, *size), c, info={"model": "rpc", "simulated": "true model"})
             for n, r, c in zip(names, rpcs, corrections)}
    step(0.05, f"writing the terrain under {len(names)} products")
    bounds = region_bounds(list(truth.values()), heights)
    with atomic_outputs() as files:
        dem_path = files.path(folder / "dem.tif")
        write_dem(dem_path, bounds, spec.centre, spec.relief, seed)
        dem = Dem(dem_path, datum="geoid")
        dem.height(np.array(bounds[0::2]), np.array(bounds[1::2]))  # one read of the whole DEM, not one per product
        near = neighbours(list(truth.values()), heights)
        step(0.1, f"drawing tie points: {settings.ties_per_product} observations per product")
        strips = None if settings.forward_ties else np.arange(len(names)) // layout.products_per_strip
        ties = draw_points(list(truth.values()), near, dem, settings.ties_per_product, 2, rng,
                           lambda f: step(0.1 + 0.5 * f, None), strip=strips)
        step(0.6, f"{ties.n_points} tie points, {ties.n_observations} observations; drawing check points")
        per = settings.gcps(len(names)) / len(names)
        checks = draw_points(list(truth.values()), near, dem, max(int(math.ceil(3 * per)), 1), 1, rng,
                             lambda f: step(0.6 + 0.1 * f, None), points_per_product=per)
        step(0.7, "writing the tie points")
        tie_data = ties.columns(names, settings.image_noise, rng, ids("T", ties.n_points))
        write_columns(files.path(folder / "tie_points.csv"), TIE_COLUMNS, tie_data)
        gcp_data = checks.columns(names, settings.image_noise, rng, ids("C", checks.n_points))
        control = np.zeros(checks.n_points, bool)
        control[rng.choice(checks.n_points, int(round((1 - settings.check_fraction) * checks.n_points)), False)] = True
        if settings.corner_gcps and checks.n_points:
            control[checks.corner_points(bounds)] = True
        gcp_data.update(checks.gcp_fields(np.nonzero(control)[0], settings.image_noise))
        write_columns(files.path(folder / "gcps.csv"), GCP_COLUMNS, gcp_data)
        step(0.85, f"writing {len(names)} RPC products and their truth")
        for name, rpc, scene in zip(names, rpcs, truth.values()):
            write_rpc(rpc, folder / "products" / f"{name}_RPC.TXT", files=files)
            save_scene(scene, folder / "truth" / f"{name}.json", files)
        manifest = _manifest(layout, spec, seed, settings, fit, heights, names, corrections, ties, checks,
                             int(control.sum()))
        write_text(folder / MANIFEST, json.dumps(manifest, indent=1), files)
    step(1.0, "region simulation written")
    return RegionResult(folder, folder / MANIFEST, folder / "dem.tif", folder / "gcps.csv", folder / "tie_points.csv",
                        {n: folder / "products" / f"{n}_RPC.TXT" for n in names},
                        {n: folder / "truth" / f"{n}.json" for n in names})


def region_bounds(scenes: list[RpcScene], heights: tuple[float, float], margin_deg: float = 0.02):
    """(lon_min, lat_min, lon_max, lat_max) degrees around every product's footprint box
    (:func:`simulation.regionpoints.boxes`), widened by margin_deg."""
    b = boxes(scenes, heights)
    return (float(b[:, 0].min()) - margin_deg, float(b[:, 1].min()) - margin_deg, float(b[:, 2].max()) + margin_deg,
            float(b[:, 3].max()) + margin_deg)


def _manifest(layout, spec, seed, settings, fit, heights, names, corrections, ties, checks, n_control) -> dict:
    per = layout.products_per_strip
    files = output_names(layout)
    return {
        "kind": "pushbroom region simulation (RPC products, no images)", "seed": seed,
        "layout": asdict(layout), "settings": asdict(settings), "preset": spec.name, "description": spec.description,
        "template": {"height_range_m": list(heights),
                     "fit_check_px": {k: fit["check"][k] for k in ("rms_px", "max_px")}},
        "points": {"tie_points": ties.n_points, "tie_observations": ties.n_observations,
                   "tie_observations_per_product": ties.per_product_summary(),
                   "check_points": checks.n_points - n_control, "control_points": n_control},
        "products": [{"name": n, "strip": k // per + 1, "index": k % per + 1, "date": layout.date(k // per),
                      "rpc": f"products/{n}_RPC.TXT", "true_scene": f"truth/{n}.json",
                      "true_correction": {"col": corrections[k, 0].tolist(), "row": corrections[k, 1].tolist()}}
                     for k, n in enumerate(names)],
        "conventions": __doc__.split("\n\n")[2].strip(),
        "files": {"dem": "dem.tif (EGM96 geoid heights)", "gcps": "gcps.csv", "tie_points": "tie_points.csv",
                  "all": files},
    }
