"""The simulated block of tests/unit/adjust/test_block.py and test_block_lines.py: three independent
simulations of the TH-1 three-line preset cut to 500 x 500 px (seeds 1, 2, 3: their own trajectory
errors, position bias 10 m and drift 0.02 m/s, attitude bias 2e-4 rad and drift 5e-7 rad/s; no
interior errors), given epochs a week apart so that they are distinct products; tie points at the
ground points of an 8 x 8 lattice of the first scene's nadir image at random heights (300-900 m)
that two camera directions see, in every camera of every TRUE scene with NOISE px; 49 check ground
points of a 7 x 7 lattice."""
from __future__ import annotations

import numpy as np

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.observations.tiepoints import TieTable
from pushbroom_adjust.simulation.presets import PRESETS, ErrorSettings, cut_preset
from pushbroom_adjust.simulation.simulator import simulate
from tests.support.block_observations import measure_block

PRESET = cut_preset(PRESETS["th1_tlc"], 500, 500)
ERRORS = ErrorSettings(position_bias=10.0, position_drift=0.02, attitude_bias=2e-4, attitude_drift=5e-7)
NOISE = 0.3  # px
SEEDS = (1, 2, 3)
# onboard sigmas as the simulated errors: 10 m (GNSS), 2e-4 rad (41 arcsec, star trackers)
SETTINGS = AdjustmentSettings(position_order=1, attitude_order=1, position_sigma=10.0, attitude_sigma=2e-4)


class SimulatedBlock:
    """True and onboard scenes (name -> SceneModel), the tie table and the check ground (ECEF);
    a subclass adds its control in :meth:`add_control`, drawing from ``self.rng`` before the check
    ground is (so each test's numbers stay those it was measured with). ``errors``: a scene's own
    onboard error magnitudes (name -> ErrorSettings), ERRORS for the others."""

    def __init__(self, folder, errors: dict[str, ErrorSettings] | None = None):
        self.rng = np.random.default_rng(0)
        self.true, self.onboard = {}, {}
        for k, seed in enumerate(SEEDS):
            name = f"S{seed}"
            sim = simulate(PRESET, folder / f"s{seed}", seed=seed, n_gcps=10, errors=(errors or {}).get(name, ERRORS))
            self.true[name], self.onboard[name] = load_scene(sim.true_scene), load_scene(sim.onboard_scene)
            for scene in (self.true[name], self.onboard[name]):
                scene.epoch = f"2010-12-{15 + 7 * k}T03:00:00.000000Z"
        ref = self.true["S1"]
        lattice = np.linspace(40.0, 460.0, 8)
        col, row = (a.ravel() for a in np.meshgrid(lattice, lattice))
        ground = ref.image_to_ground(col, row, self.rng.uniform(300.0, 900.0, col.size), 0)
        # points seen by the nadir cameras only meet in near-parallel rays (the three simulations share
        # their orbit): their heights are undetermined, so only points seen in two directions are kept
        m = self.measure(ground)
        directions = np.unique(np.stack([m["point"].astype(str), m["camera"]], axis=1), axis=0)[:, 0]
        ids, counts = np.unique(directions.astype(int), return_counts=True)
        self.tie_ground = ground[ids[counts >= 2]]
        m = self.measure(self.tie_ground)
        self.ties = TieTable(np.char.add("T", m["point"].astype(str)), m["camera"], m["col"], m["row"], NOISE,
                             m["scene"])
        self.add_control(ref)
        lattice = np.linspace(30.0, 470.0, 7)
        col, row = (a.ravel() for a in np.meshgrid(lattice, lattice))
        self.check_ground = ref.image_to_ground(col, row, self.rng.uniform(300.0, 900.0, col.size), 0)

    def add_control(self, ref) -> None:
        """The subclass's control (GCPs, lines), ``ref`` the first true scene."""

    def measure(self, ground: np.ndarray) -> dict:
        """Observations of ECEF points (p, 3) in every camera of every true scene that sees them
        (5 px inside the image), with NOISE px: point (index), scene, camera, col, row arrays."""
        return measure_block(self.true, ground, self.rng, NOISE)

    def check_px(self, name: str, adjusted) -> float:
        """RMS (px) over the scene's cameras of the check ground through ``adjusted`` against the truth."""
        true, d = self.true[name], []
        for c, cam in enumerate(true.cameras):
            t = np.stack(true.ground_to_image(self.check_ground, c), axis=1)
            a = np.stack(adjusted.ground_to_image(self.check_ground, c), axis=1)
            inside = (t[:, 0] > 0) & (t[:, 0] < cam.cols) & (t[:, 1] > 0) & (t[:, 1] < cam.rows)
            d.append(np.hypot(*(a - t)[inside].T))
        return float(np.sqrt(np.mean(np.concatenate(d) ** 2)))
