"""A mixed block with known truth (issue 23): two rigorous scenes and RPC products of another date
and sensor, for :func:`core.adjust.block.adjust_block`.

Rigorous: two independent simulations of the TH-1 three-line preset cut to 500 x 500 px (seeds 1
and 2, trajectory errors as tests/unit/adjust/test_block.py: position bias 10 m and drift 0.02 m/s,
attitude bias 2e-4 rad and drift 5e-7 rad/s; no interior errors), epochs a week apart.

RPC: a single-line camera of another sensor (focal 1.7 m, 7 um pitch, 505 km, 2.1 m GSD: ZY-3's
nadir optics, which cut_preset cannot cut (three CCDs), as one line of 500 px, looking 20 deg
forward), simulated on its own orbit (inclination 97.4 deg) over the same ground centre; its TRUE scene
fitted by an RPC00B model (:func:`core.products.rpcfit.fit_rpc`, about 1e-4 px), and the vendor's
RPC that RPC with a known image bias folded in (:func:`core.products.rpcfit.refined_rpc`, exact):
col + 3.2 px, row - 2.5 px + 4e-3 per row (2 px at the last row). The correction that undoes it is
known exactly (:data:`TRUE_CORRECTION`, drift mode). S1's nadir and S2's forward camera, fitted
the same way, make RPC products too (for a block of RPC images only), with shifts of their own
(:data:`PRODUCTS`).

Observations: ground points at random heights (300-900 m) projected through the TRUE models plus
0.3 px noise (the RPC images' through their true RPC): tie points on a 9 x 9 lattice of the first
scene's nadir image and a 7 x 7 lattice of R's image, kept where seen in two scenes or more; check
points on 7 x 7 lattices of both; control points near the corners of both, or on 3 x 3 lattices of
S1's nadir, S2's forward and R's image; every row naming its scene.
"""
from __future__ import annotations

import math

import numpy as np

from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.model.rpcscene import RpcCamera, RpcScene
from pushbroom_adjust.core.observations.gcps import GcpTable
from pushbroom_adjust.core.observations.tiepoints import TieTable
from pushbroom_adjust.core.products.rpcfit import fit_rpc, refined_rpc
from pushbroom_adjust.simulation.presets import PRESETS, CameraSpec, ErrorSettings, Preset, cut_preset
from pushbroom_adjust.simulation.simulator import simulate
from tests.support.block_observations import measure_block

TH1 = cut_preset(PRESETS["th1_tlc"], 500, 500)
OTHER = Preset("other_sensor", "single-line camera of ZY-3 nadir's optics, 505 km, 2.1 m GSD, 500 x 500 px", 505e3,
               (CameraSpec("PAN", 1.7, 7e-6, 1, 500, tilt=math.radians(20.0)),), 500, ErrorSettings(), inclination=math.radians(97.4),
               centre=TH1.centre)
ERRORS = ErrorSettings(position_bias=10.0, position_drift=0.02, attitude_bias=2e-4, attitude_drift=5e-7)
NOISE = 0.3  # px
HEIGHTS = (300.0, 900.0)  # m: the ground points' heights
RPC_HEIGHTS = (0.0, 1200.0)  # m: the height range the RPCs are fitted over
BIAS = np.array([[3.2, 0.0, 0.0], [-2.5, 0.0, 4e-3]])
"""The vendor RPC's image bias (the correction layout): col + a0, row + b0 + b2 * row."""
TRUE_CORRECTION = np.array([[-BIAS[0, 0], 0.0, 0.0],
                            [-BIAS[1, 0] / (1.0 + BIAS[1, 2]), 0.0, -BIAS[1, 2] / (1.0 + BIAS[1, 2])]])
"""The correction of the vendor RPC that gives the true one back."""
PRODUCTS = {"S1": (0, np.array([[-4.0, 0.0, 0.0], [1.5, 0.0, 0.0]])), "S2": (1, np.array([[2.0, 0.0, 0.0],
                                                                                   [3.0, 0.0, 0.0]]))}
"""The rigorous scenes' cameras delivered as RPC products too (S1's NAD, S2's FWD: 25 deg apart)
and their image biases (shifts, px)."""


def rpc_product(scene, camera: int, name: str, bias: np.ndarray) -> tuple[RpcScene, RpcScene]:
    """(the true RPC scene, the vendor's: the true RPC with ``bias`` folded in) of one camera of a
    rigorous true scene, fitted over RPC_HEIGHTS."""
    rpc, _ = fit_rpc(scene, camera, RPC_HEIGHTS)
    cam = scene.cameras[camera]
    true = RpcScene(rpc, RpcCamera(name, cam.cols, cam.rows))
    vendor, how = refined_rpc(RpcScene(rpc, true.camera, bias))
    assert how == "folded"
    return true, RpcScene(vendor, RpcCamera(name, cam.cols, cam.rows))


class MixedBlock:
    """true / onboard: name -> scene (S1, S2 rigorous; R the other sensor's RPC product: true RPC
    and vendor RPC); rpc_true / rpc_vendor: S1's NAD, S2's FWD and R as RPC products (for a block
    of RPC images only); ties, gcps (control and check rows, every row naming its scene)."""

    def __init__(self, folder):
        self.rng = np.random.default_rng(0)
        self.true, self.onboard = {}, {}
        for k, seed in enumerate((1, 2)):
            sim = simulate(TH1, folder / f"s{seed}", seed=seed, n_gcps=10, errors=ERRORS)
            name = f"S{seed}"
            self.true[name], self.onboard[name] = load_scene(sim.true_scene), load_scene(sim.onboard_scene)
            for scene in (self.true[name], self.onboard[name]):
                scene.epoch = f"2010-12-{15 + 7 * k}T03:00:00.000000Z"
        other = load_scene(simulate(OTHER, folder / "other", seed=3, n_gcps=10, errors=ERRORS).true_scene)
        self.true["R"], self.onboard["R"] = rpc_product(other, 0, "PAN", BIAS)
        self.rpc_true, self.rpc_vendor = {"R": self.true["R"]}, {"R": self.onboard["R"]}
        for name, (camera, bias) in PRODUCTS.items():
            self.rpc_true[name], self.rpc_vendor[name] = rpc_product(self.true[name], camera,
                                                                     self.true[name].cameras[camera].name, bias)
        ref = self.true["S1"]
        lattice = np.linspace(40.0, 460.0, 9)
        col, row = (a.ravel() for a in np.meshgrid(lattice, lattice))
        inner = np.linspace(40.0, 460.0, 7)
        c, r = (a.ravel() for a in np.meshgrid(inner, inner))
        self.tie_ground = np.concatenate([ref.image_to_ground(col, row, self.rng.uniform(*HEIGHTS, col.size), 0),
                                          self.true["R"].image_to_ground(c, r, self.rng.uniform(*HEIGHTS, c.size))])
        lattice = np.linspace(30.0, 470.0, 7)
        c, r = (a.ravel() for a in np.meshgrid(lattice, lattice))
        self.check_ground = np.concatenate([ref.image_to_ground(c, r, self.rng.uniform(*HEIGHTS, c.size), 0),
                                            self.true["R"].image_to_ground(c, r, self.rng.uniform(*HEIGHTS, c.size))])
        # control: near the corners of S1's nadir image and of R's image (1 km across, in S1's middle);
        # or on 3 x 3 lattices of S1's nadir, S2's forward and R's image
        self.control = {"corners": self.lattices([(self.true["S1"], 0), (self.true["R"], 0)], 2),
                        "lattices": self.lattices([(self.true["S1"], 0), (self.true["S2"], 1), (self.true["R"], 0)],
                                                  3)}

    def lattices(self, images: list, n: int) -> np.ndarray:
        """Ground points (k, 3) ECEF m at random HEIGHTS under an n x n lattice (80 to 420 px) of
        each (scene, camera) of ``images``."""
        nodes = np.linspace(80.0, 420.0, n)
        c, r = (a.ravel() for a in np.meshgrid(nodes, nodes))
        return np.concatenate([scene.image_to_ground(c, r, self.rng.uniform(*HEIGHTS, c.size), camera)
                               for scene, camera in images])

    def tables(self, scenes: dict, control: str = "corners") -> tuple[TieTable, GcpTable, dict]:
        """(tie table, GCP table (control then check rows), the rows' true (col, row)) of
        observations in ``scenes`` (name -> true scene), with the control points ``control`` (a key
        of :attr:`control`): tie points seen in two scenes or more and by two camera directions or
        more (NAD, FWD, BWD, the other sensor's PAN): points seen by nadir cameras only meet in
        near-parallel rays, at undetermined heights."""
        m = measure_block(scenes, self.tie_ground, self.rng, NOISE)
        keep = (_kinds(m["point"], m["scene"]) >= 2) & (_kinds(m["point"], m["camera"]) >= 2)
        ties = TieTable(np.char.add("T", m["point"][keep].astype(str)), m["camera"][keep], m["col"][keep],
                        m["row"][keep], NOISE, m["scene"][keep])
        ground = np.concatenate([self.control[control], self.check_ground])
        g = measure_block(scenes, ground, self.rng, NOISE)
        lon, lat, h = ecef_to_geodetic(ground[g["point"]])
        role = np.where(g["point"] < self.control[control].shape[0], "control", "check")
        order = np.argsort(role == "check", kind="stable")
        gcps = GcpTable(np.char.add("G", g["point"].astype(str)), role, g["camera"], g["col"], g["row"], lon, lat,
                        h, NOISE, 0.1, 0.2, scene=g["scene"]).select(order)
        truth = {k: g[k][order] for k in ("true_col", "true_row")}
        return ties, gcps, truth


def _kinds(point: np.ndarray, label: np.ndarray) -> np.ndarray:
    """Per observation (n,): how many distinct ``label`` values (n,) its point's observations have."""
    pairs = np.unique(np.stack([point, np.unique(label, return_inverse=True)[1]], axis=1), axis=0)
    return np.bincount(pairs[:, 0], minlength=point.max() + 1)[point]


def floor_px(gcps: GcpTable, truth: dict, scene: str) -> float:
    """The check observations' noise floor in ``scene`` (px): the RMS length of their measured
    minus true image positions, i.e. their residuals through the true models."""
    m = (gcps.role == "check") & (gcps.scene == scene)
    return float(np.sqrt(np.mean((gcps.col[m] - truth["true_col"][m]) ** 2 + (gcps.row[m] - truth["true_row"][m]) ** 2)))
