"""SCENE or SCENES: the parameters of algorithms that work on one scene or on a block of scenes
(the scenes themselves are read by :mod:`core.runs.scenes`)."""
from __future__ import annotations

from qgis.core import QgsProcessingException

from .parameters import SCENE, SCENES


def one_scene_file(alg, parameters, context) -> str:
    """SCENE's file when SCENES is not given; QgsProcessingException naming both when neither is."""
    path = alg.parameterAsFile(parameters, SCENE, context)
    if not path:
        raise QgsProcessingException(f"give {SCENE} (one scene) or {SCENES} (a block of scenes): neither is given")
    return path


def scene_files(alg, parameters, context) -> list[str]:
    """The files of SCENES ([] when not given: QGIS 3.22 reads an empty list as [''])."""
    return [path for path in alg.parameterAsFileList(parameters, SCENES, context) if path]


def block_given(alg, parameters, context) -> bool:
    """Whether SCENES is given (a block of scenes); QgsProcessingException naming both parameters,
    and what the algorithm does with each (its SCENE_OR_SCENES), when SCENE is given too."""
    if not scene_files(alg, parameters, context):
        return False
    if alg.parameterAsFile(parameters, SCENE, context):
        one, block = alg.SCENE_OR_SCENES
        raise QgsProcessingException(f"{SCENE} and {SCENES} are both given: give {SCENE} to {one}, or {SCENES} to "
                                     f"{block}, not both")
    return True


def scene_or_block(alg, parameters, context) -> tuple[str, tuple[str, ...]]:
    """(SCENE's file, ()) for one scene, ('', SCENES' files) for a block (:func:`block_given`)."""
    if block_given(alg, parameters, context):
        return "", tuple(scene_files(alg, parameters, context))
    return one_scene_file(alg, parameters, context), ()
