"""Per-scene onboard and vendor sigmas of a block (:attr:`core.adjust.settings.AdjustmentSettings.
scene_sigmas`): a block mixes products of different accuracy (a scene with star trackers good to a
few arcseconds beside an older one good to 30, an RPC product whose vendor states 5 px beside one
stating 10 px), so each scene's pseudo-observations (rigorous scenes: POSITION_SIGMA m,
ATTITUDE_SIGMA rad) or prior (RPC products: RPC_SIGMA px) may carry its own sigma.

The global sigma still decides whether those pseudo-observations exist at all, and so how the datum
is held (:func:`core.adjust.ties.datum`, unchanged): an override is refused where the global value
is not given. The variance component of each pseudo-observation group (position, attitude, RPC
prior) stays one factor on the stated sigmas of all scenes, as without overrides.
"""
from __future__ import annotations

import math

from ..errors import InputError
from ..model.block import SEPARATOR
from ..rotations import ARCSEC
from .settings import PARAMETERS, AdjustmentSettings

RIGOROUS_SIGMAS = ("position_sigma", "attitude_sigma")  # an RPC product has no onboard trajectory
# SCENE_SIGMAS as given: rows of a scene name and its sigmas in the units of POSITION_SIGMA, ATTITUDE_SIGMA and
# RPC_SIGMA; per value column the core's sigma and the factor from the column's unit to the core's (m, rad, px)
HEADERS = ("scene", "position_sigma_m", "attitude_sigma_arcsec", "rpc_sigma_px")
COLUMNS = (("position_sigma", 1.0), ("attitude_sigma", ARCSEC), ("rpc_sigma", 1.0))


def read_scene_sigmas(values, names: list[str]) -> dict[str, dict[str, float]]:
    """{scene: {core sigma: value in the core's unit (m, rad, px)}} of SCENE_SIGMAS ``values`` (texts,
    row by row under HEADERS, '' for an empty cell) for the block's scene ``names``. InputError
    (parameter settings.scene_sigmas) naming the row and what was expected for: values that are not
    whole rows, a row without a scene, a scene not in the block or given twice, a value that is not a
    positive number, a row without any value. (Bounds and the block's kinds of scene:
    :meth:`AdjustmentSettings.validate`, :func:`check_scene_sigmas`.)"""
    values, width = list(values), len(HEADERS)
    if len(values) % width:
        raise InputError(f"SCENE_SIGMAS: {len(values)} values are not whole rows; expected rows of {width} values "
                         f"({', '.join(HEADERS)}), an empty value where the global one is kept",
                         parameter="settings.scene_sigmas")
    out: dict[str, dict[str, float]] = {}
    for r in range(len(values) // width):
        scene, *cells = values[r * width:(r + 1) * width]
        where = f"SCENE_SIGMAS: row {r + 1}"
        if scene not in names:
            got = f"scene {scene!r} is not in SCENES" if scene else "no scene is named"
            raise InputError(f"{where}: {got}; expected one of the block's scenes ({', '.join(names)}: the file's "
                             "stem, or the folder's for onboard_scene.json)", parameter="settings.scene_sigmas")
        if scene in out:
            raise InputError(f"{where}: scene {scene!r} is given twice; expected one row per scene",
                             parameter="settings.scene_sigmas")
        own = {key: _positive(cell, f"{where} ({scene}): {header}") * factor
               for header, (key, factor), cell in zip(HEADERS[1:], COLUMNS, cells) if cell}
        if not own:
            raise InputError(f"{where} ({scene}): no value; expected at least one of {', '.join(HEADERS[1:])}",
                             parameter="settings.scene_sigmas")
        out[scene] = own
    return out


def _positive(cell: str, what: str) -> float:
    """The number of a SCENE_SIGMAS cell; InputError starting with ``what`` unless it is positive and finite."""
    try:
        value = float(cell)
    except ValueError:
        value = math.nan
    if not value > 0 or math.isinf(value):
        raise InputError(f"{what} {cell!r} is not a positive number; expected a positive number or an empty cell "
                         "(the global value)", parameter="settings.scene_sigmas")
    return value


def check_scene_sigmas(scenes: dict, settings: AdjustmentSettings) -> None:
    """InputError (parameter settings.scene_sigmas) for an override of settings.scene_sigmas that
    the block ``scenes`` (name -> SceneModel or RpcScene) cannot take: a scene not in the block
    (naming the block's scenes), a sigma whose global value is not given (it decides the datum),
    rpc_sigma for a rigorous scene or an onboard sigma for an RPC product. The settings are
    validated first (bounds, keys)."""
    settings.validate()
    for scene, sigmas in settings.scene_sigmas.items():
        if scene not in scenes:
            raise InputError(f"SCENE_SIGMAS: scene {scene!r} is not in the block (scenes: {', '.join(scenes)})",
                             parameter="settings.scene_sigmas")
        rpc = bool(scenes[scene].rpc_images())
        wrong = [k for k in sigmas if (k in RIGOROUS_SIGMAS) == rpc]
        if wrong:
            what = "an RPC product: it has no onboard trajectory (its prior is RPC_SIGMA)" if rpc else \
                "a rigorous scene: RPC_SIGMA is the prior of RPC products (its own are POSITION_SIGMA, ATTITUDE_SIGMA)"
            raise InputError(f"SCENE_SIGMAS: scene {scene!r} is {what}; remove its "
                             f"{', '.join(PARAMETERS[k] for k in wrong)}",
                             parameter="settings.scene_sigmas")
        unset = [k for k in sigmas if getattr(settings, k) is None]
        if unset:
            given = " and ".join(PARAMETERS[k] for k in unset)
            raise InputError(f"SCENE_SIGMAS: scene {scene!r} overrides {given}, whose global value is not "
                             f"given (no such pseudo-observations in the block): give {given} too; per-scene values "
                             "override it", parameter="settings.scene_sigmas")


def camera_scene(camera: str) -> str:
    """The block scene of a composite camera name ``<scene>/<camera>`` ('' for a camera of one scene)."""
    scene, separator, _ = camera.partition(SEPARATOR)
    return scene if separator else ""


def stated_sigmas(settings: AdjustmentSettings, scene: str, rpc: bool) -> dict:
    """The sigmas the block used for ``scene`` (JSON-ready): an RPC product's rpc_sigma_px, a
    rigorous scene's position_sigma_m and attitude_sigma_arcsec (None where not given), and
    ``own``: the keys it set itself in settings.scene_sigmas (the others are the global values)."""
    if rpc:
        out = {"rpc_sigma_px": settings.sigma("rpc_sigma", scene)}
    else:
        attitude = settings.sigma("attitude_sigma", scene)
        out = {"position_sigma_m": settings.sigma("position_sigma", scene),
               "attitude_sigma_arcsec": None if attitude is None else attitude / ARCSEC}
    return {**out, "own": sorted(settings.scene_sigmas.get(scene, {}))}


def sigmas_text(stated: dict) -> str:
    """``stated`` (:func:`stated_sigmas`) in words: '10 m, 41.3 arcsec' or '5 px', '(own)' after a
    scene's own values, '-' for a sigma not given."""
    def value(key: str, unit: str) -> str:
        v = stated[key]
        own = " (own)" if key.rsplit("_", 1)[0] in stated["own"] else ""
        return f"- {unit}" if v is None else f"{v:.4g} {unit}{own}"

    if "rpc_sigma_px" in stated:
        return value("rpc_sigma_px", "px")
    return f"{value('position_sigma_m', 'm')}, {value('attitude_sigma_arcsec', 'arcsec')}"
