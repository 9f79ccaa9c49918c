"""SCENE_SIGMAS of pushbroom:bundleadjust with SCENES: each scene's own onboard or vendor sigmas
(:attr:`core.adjust.settings.AdjustmentSettings.scene_sigmas`, :mod:`core.adjust.scenesigmas`), a
matrix of one row per scene: scene, position_sigma_m, attitude_sigma_arcsec, rpc_sigma_px (the
units of POSITION_SIGMA, ATTITUDE_SIGMA and RPC_SIGMA), an empty cell keeping the global value.

Processing gives the matrix as one flat list of values, row by row (processing.run, a graphical
model); qgis_process as the parameter repeated once per value or as one comma-separated text,
which QGIS splits (``SCENE_SIGMAS=old,,60,`` or ``SCENE_SIGMAS=old SCENE_SIGMAS= ...``).
"""
from __future__ import annotations

import math

from qgis.core import QgsProcessingException, QgsProcessingParameterMatrix

from ..core.rotations import ARCSEC
from .inputs import attribute_texts
from .parameters import SCENE, SCENES, tr

SCENE_SIGMAS = "SCENE_SIGMAS"
HEADERS = ["scene", "position_sigma_m", "attitude_sigma_arcsec", "rpc_sigma_px"]
# per value column: the core's sigma and the factor from the column's unit to the core's (m, rad, px)
COLUMNS = (("position_sigma", 1.0), ("attitude_sigma", ARCSEC), ("rpc_sigma", 1.0))
HELP = (
    "Optional, with SCENES: each scene's own onboard or vendor accuracy. One row per scene: scene (as SCENES names "
    "it), position_sigma_m, attitude_sigma_arcsec, rpc_sigma_px; an empty cell keeps the global value, which must "
    "still be given. qgis_process: SCENE_SIGMAS=old,,60, (docs page).")


def scene_sigmas_parameter() -> QgsProcessingParameterMatrix:
    """SCENE_SIGMAS: a matrix of any number of rows under HEADERS, optional."""
    parameter = QgsProcessingParameterMatrix(SCENE_SIGMAS, tr("Per-scene onboard / vendor sigmas (block)"),
                                             numberRows=0, hasFixedNumberRows=False, headers=HEADERS, optional=True)
    parameter.setHelp(tr(HELP))
    return parameter


def matrix_values(alg, parameters, context) -> list[str]:
    """SCENE_SIGMAS's values as stripped texts, row by row ([] when not given: a NULL, an empty
    text or list); a whole number's text without '.0' (a scene named '2021' read back as 2021.0)."""
    if SCENE_SIGMAS not in parameters:
        return []
    values = alg.parameterAsMatrix(parameters, SCENE_SIGMAS, context)
    values = [int(v) if isinstance(v, float) and v.is_integer() else v for v in values]
    texts = attribute_texts(values)
    return [] if not any(texts) else texts


def refuse_for_one_scene(alg, parameters, context) -> None:
    """SCENE_SIGMAS given with one SCENE: refused (one scene takes the global sigmas)."""
    if matrix_values(alg, parameters, context):
        raise QgsProcessingException(f"{SCENE_SIGMAS}: per-scene sigmas are for a block of scenes ({SCENES}); one "
                                     f"{SCENE} takes POSITION_SIGMA, ATTITUDE_SIGMA and RPC_SIGMA: leave "
                                     f"{SCENE_SIGMAS} empty")


def scene_sigmas(alg, parameters, context, names: list[str]) -> dict[str, dict[str, float]]:
    """{scene: {core sigma: value in the core's unit (m, rad, px)}} of SCENE_SIGMAS for the block's
    scene ``names``. QgsProcessingException naming SCENE_SIGMAS, the row and what was expected for:
    values that are not whole rows, a row without a scene, a scene not in SCENES or given twice, a
    value that is not a positive number, a row without any value."""
    values = matrix_values(alg, parameters, context)
    width = len(HEADERS)
    if len(values) % width:
        raise QgsProcessingException(f"{SCENE_SIGMAS}: {len(values)} values are not whole rows; expected rows of "
                                     f"{width} values ({', '.join(HEADERS)}), an empty value where the global one "
                                     "is kept")
    out: dict[str, dict[str, float]] = {}
    for r in range(len(values) // width):
        scene, *cells = values[r * width:(r + 1) * width]
        where = f"{SCENE_SIGMAS}: row {r + 1}"
        if scene not in names:
            got = f"scene {scene!r} is not in {SCENES}" if scene else "no scene is named"
            raise QgsProcessingException(f"{where}: {got}; expected one of the block's scenes ({', '.join(names)}: "
                                         "the file's stem, or the folder's for onboard_scene.json)")
        if scene in out:
            raise QgsProcessingException(f"{where}: scene {scene!r} is given twice; expected one row per scene")
        own = {}
        for header, (key, factor), cell in zip(HEADERS[1:], COLUMNS, cells):
            if not cell:
                continue
            try:
                value = float(cell)
            except ValueError:
                value = math.nan
            if not value > 0 or math.isinf(value):
                raise QgsProcessingException(f"{where} ({scene}): {header} {cell!r} is not a positive number; "
                                             "expected a positive number or an empty cell (the global value)")
            own[key] = value * factor
        if not own:
            raise QgsProcessingException(f"{where} ({scene}): no value; expected at least one of "
                                         f"{', '.join(HEADERS[1:])}")
        out[scene] = own
    return out
