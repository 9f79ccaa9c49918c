"""Where a re-adjustment starts: the corrections an adjusted scene already carries."""
from __future__ import annotations

from ..errors import InputError
from ..model.sensor import SceneModel
from .parameters import ParameterSet


def start_from_existing_correction(scene: SceneModel, params: ParameterSet) -> None:
    """Re-adjusting an adjusted scene starts from its correction(s) when the models agree: a
    shared correction starts every camera's of a per-camera run; corrections per camera
    cannot start a shared one."""
    platform = scene.platform
    position, attitude = params.block_values("position"), params.block_values("attitude")
    for o, cams in enumerate(params.owners):
        starts = [platform.for_camera(scene.cameras[c].name).correction for c in cams]
        if any(corr is not starts[0] for corr in starts):
            own = [scene.cameras[c].name for c in cams]
            raise InputError(f"the scene was adjusted with a trajectory correction per camera ({', '.join(own)}); "
                             "adjust it again with one correction per camera, or adjust the original (onboard) "
                             "scene", parameter="scene")
        corr = starts[0]
        if corr is None:
            continue
        if corr.position.to_dict() != params.bases["position"][o].to_dict() or \
                corr.attitude.to_dict() != params.bases["attitude"][o].to_dict():
            raise InputError("the scene was adjusted with another trajectory model; adjust the original (onboard) "
                             "scene, or choose the same model and interval", parameter="scene")
        position[params.owner_rows("position", o)] = corr.position_coefficients
        attitude[params.owner_rows("attitude", o)] = corr.attitude_coefficients
    values = params.values()
    values[params.block_indices("position")] = position
    values[params.block_indices("attitude")] = attitude
    params.set_values(values)
