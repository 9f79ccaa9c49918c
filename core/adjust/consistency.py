"""The adjusted scene as it will be written, checked against the solution it was made from.

The adjustment fits its own model of the scene (:mod:`core.adjust.model`: analytic corrections on
the measured trajectory); the scene it writes evaluates the same corrections through the sensor
model (:class:`core.model.sensor.SceneModel`, baked into its trajectory, cameras and chips) or the
RPC and its correction. Any difference between the two (a term the writer drops, a convention the
model and the sensor disagree on, a velocity or a time left uncorrected) would make every product
of the written scene miss what the adjustment reports, silently. So the written scene, after a
round trip through the scene JSON (a block's: each of its scenes'), images every fitted
observation's ground point (control, tie and line points at their adjusted positions) on the
observation's own chip, and the run fails with a
:class:`core.errors.ConsistencyError` naming the largest difference when one exceeds
FITTED_TOLERANCE.
"""
from __future__ import annotations

import numpy as np

from ..errors import ConsistencyError
from ..formats.scene_json import rpc_scene_from_dict, rpc_scene_to_dict, scene_from_dict, scene_to_dict
from ..model.block import compose_block, is_block, split_block
from ..model.mixedblock import MixedBlock
from ..model.rpcscene import RpcScene
from ..model.sensor import SceneModel, rows_by
from .problem import Problem

FITTED_TOLERANCE = 0.01  # px: the written scene against the fitted image positions


class _Written:
    """Each kind of scene as it reads back from what is written of it (asked through ``answer``,
    :mod:`core.model.kinds`)."""

    def rigorous(self, scene: SceneModel) -> SceneModel:
        """Its scene JSON read back; a block's composite as its scenes read back
        (:func:`core.model.block.split_block`), composed again."""
        if is_block(scene):
            return compose_block({name: self.rigorous(s) for name, s in split_block(scene).items()})
        return scene_from_dict(scene_to_dict(scene), "the adjusted scene")

    def rpc(self, scene: RpcScene) -> RpcScene:
        """Its RPC scene JSON read back."""
        return rpc_scene_from_dict(rpc_scene_to_dict(scene), "the adjusted scene")

    def block(self, scene: MixedBlock) -> MixedBlock:
        """Its parts read back."""
        rigorous = scene.rigorous_part()
        return scene.with_parts(None if rigorous is None else self.rigorous(rigorous),
                                {name: self.rpc(img) for name, img in scene.images.items()})


def written(scene: SceneModel | RpcScene | MixedBlock) -> SceneModel | RpcScene | MixedBlock:
    """``scene`` as it reads back from its scene JSON; a block's composite as its scenes read
    back, composed again; a block with RPC images as its parts read back (:class:`_Written`)."""
    return scene.answer(_Written())


def check_written_scene(problem: Problem, scene: SceneModel | RpcScene) -> dict:
    """Where the written ``scene`` images the ground points of ``problem``'s observations, against
    where its solution fitted them (measured + residual). Returns {"max_px", "rms_px",
    "observations"}; ConsistencyError beyond FITTED_TOLERANCE (or where it images nothing)."""
    obs = problem.obs
    fitted = problem.residuals() + np.stack([obs.col, obs.row], axis=1)
    x = problem.ground[obs.point]
    back = written(scene)
    imaged = np.full_like(fitted, np.nan)
    for c, m in enumerate(rows_by(obs.camera, len(scene.cameras))):
        if not m.size:
            continue
        imaged[m, 0], imaged[m, 1] = back.ground_to_image_on_chip(x[m], c, obs.chip[m], fitted[m, 0], fitted[m, 1])
    miss = np.hypot(*(imaged - fitted).T)
    bad = ~(miss <= FITTED_TOLERANCE)
    if bad.any():
        worst = int(np.argmax(np.where(np.isfinite(miss), miss, np.inf)))
        camera = scene.cameras[int(obs.camera[worst])].name
        raise ConsistencyError(
            f"the adjusted scene as it would be written does not reproduce the adjustment's solution: it images "
            f"{int(bad.sum())} of {len(obs)} fitted observations more than {FITTED_TOLERANCE} px away from where "
            f"the adjustment fitted them (largest {miss[worst]:.4g} px, camera {camera}, fitted at col "
            f"{fitted[worst, 0]:.2f}, row {fitted[worst, 1]:.2f}); the scene model and the adjustment's model "
            "disagree, so nothing was written. Please report this with the inputs.")
    return {"max_px": float(miss.max(initial=0.0)), "rms_px": float(np.sqrt(np.mean(miss ** 2))) if miss.size
            else 0.0, "observations": int(len(obs))}
