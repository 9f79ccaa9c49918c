"""A block with RPC images: the rigorous scenes' composite (:func:`core.model.block.compose_block`)
and RPC scenes (:class:`core.model.rpcscene.RpcScene`), as one scene whose cameras are the
composite's followed by each RPC image, named ``<scene>/<camera>`` alike.

:class:`MixedBlock` offers the interface the algorithms use on a scene (cameras, camera_index,
height_range, info, ground_to_image, image_to_ground, line_of_sight, ground_to_image_on_chip),
passing each call to the scene that camera belongs to, so that tie-point intersection, check
points and the adjustment's stages treat the block as one scene. An RPC image has no platform: its
line of sight is the line through the ground it sees at the top and the bottom of its RPC's height
range (:meth:`MixedBlock.line_of_sight`), which is its ray as far as the RPC describes one.

Frames and units as in core.model.sensor: ECEF metres (n, 3), GDAL (col, row) pixels, ellipsoidal
heights in metres. The composite is never written: :meth:`MixedBlock.split` gives the scenes.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError
from .block import block_camera, check_scene_names, compose_block, split_block
from .rpcscene import RpcScene
from .sensor import SceneModel


@dataclass
class MixedBlock:
    """rigorous: the composite of the block's rigorous scenes (None: RPC images only); images: scene
    name -> RpcScene with its camera named ``<scene>/<camera>``; order: the block's scene names in
    their order; info: the block's own (an adjustment's record, passed to every scene on split)."""
    rigorous: SceneModel | None
    images: dict[str, RpcScene]
    order: list[str]
    info: dict = field(default_factory=dict)
    # the scenes' height ranges do not change: the block's is computed once (a report asks it per image: a
    # thousand images each a thousand times)
    _height_range: tuple[float, float] | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def cameras(self) -> list:
        """The composite's cameras, then each RPC image's (one per image)."""
        return (list(self.rigorous.cameras) if self.rigorous is not None else []) + \
            [img.camera for img in self.images.values()]

    @property
    def n_rigorous(self) -> int:
        """How many of :attr:`cameras` (the first ones) are rigorous cameras."""
        return 0 if self.rigorous is None else len(self.rigorous.cameras)

    def camera_index(self, camera: int | str) -> int:
        """Index of a camera given by index or name; InputError naming the choices."""
        names = [c.name for c in self.cameras]
        if isinstance(camera, str):
            if camera not in names:
                raise InputError(f"camera {camera!r} is not in this block (cameras: {', '.join(names)})")
            return names.index(camera)
        if not 0 <= int(camera) < len(names):
            raise InputError(f"camera index {camera} is out of range (the block has {len(names)} cameras)")
        return int(camera)

    def part(self, camera: int) -> tuple[SceneModel | RpcScene, int]:
        """(the scene camera ``camera`` belongs to, its index there)."""
        if camera < self.n_rigorous:
            return self.rigorous, camera
        return list(self.images.values())[camera - self.n_rigorous], 0

    @property
    def height_range(self) -> tuple[float, float]:
        """(lowest, highest) ellipsoidal height (m) of the scenes' height ranges."""
        if self._height_range is None:
            ranges = [s.height_range for s in ([self.rigorous] if self.rigorous is not None else [])
                      + list(self.images.values())]
            self._height_range = (min(r[0] for r in ranges), max(r[1] for r in ranges))
        return self._height_range

    def platform_of(self, camera: int):
        """The trajectory a rigorous camera sees; None for an RPC image (no platform)."""
        scene, c = self.part(camera)
        return scene.platform_of(c)

    # --- image <-> ground, by the camera's own scene ---------------------------------------------
    def ground_to_image(self, xyz, camera: int = 0, **kwargs) -> tuple[np.ndarray, np.ndarray]:
        scene, c = self.part(self.camera_index(camera))
        return scene.ground_to_image(xyz, c, **kwargs)

    def image_to_ground(self, col, row, height, camera: int = 0) -> np.ndarray:
        scene, c = self.part(self.camera_index(camera))
        return scene.image_to_ground(col, row, height, c)

    def ground_to_image_near(self, xyz, camera: int, col, row) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`SceneModel.ground_to_image_near` of the camera's own scene (an RPC image needs
        no first guesses: :meth:`RpcScene.ground_to_image_near`)."""
        scene, c = self.part(self.camera_index(camera))
        return scene.ground_to_image_near(xyz, c, col, row)

    def ground_to_image_on_chip(self, xyz, camera: int, chip, col, row) -> tuple[np.ndarray, np.ndarray]:
        """A rigorous camera's :meth:`SceneModel.ground_to_image_on_chip`; an RPC image (one chip)
        its ground_to_image."""
        scene, c = self.part(self.camera_index(camera))
        return scene.ground_to_image_on_chip(xyz, c, chip, col, row)

    def line_of_sight(self, col, row, camera: int = 0):
        """(t (n,) s, S (n,3) ECEF m, v (n,3) m/s, u (n,3) unit directions ECEF) as
        :meth:`SceneModel.line_of_sight`; for an RPC image t and v are 0, S the ground it sees at
        the top of its RPC's height range and u the direction down to the ground it sees at the
        bottom (beyond them the RPC is extrapolated)."""
        scene, c = self.part(self.camera_index(camera))
        return scene.line_of_sight(col, row, c)

    # --- the scenes ----------------------------------------------------------------------------
    def split(self) -> dict:
        """The block's scenes (name -> SceneModel or RpcScene, block order), each with its own
        camera names and this block's info (e.g. an adjustment's record) added to its own."""
        out = {}
        if self.rigorous is not None:
            composite = replace(self.rigorous, info={**self.rigorous.info, **self.info})
            out.update(split_block(composite))
        for name, img in self.images.items():
            own = img.camera.name[len(block_camera(name, "")):]
            out[name] = RpcScene(img.rpc, replace(img.camera, name=own), img.correction.copy(),
                                 {**img.info, **self.info})
        return {name: out[name] for name in self.order}

    def with_parts(self, rigorous: SceneModel | None, images: dict[str, RpcScene]) -> "MixedBlock":
        """This block with other scenes in its parts (e.g. adjusted ones), its info copied."""
        return MixedBlock(rigorous, images, list(self.order), dict(self.info))

    # --- what it answers of its kind (core.model.kinds) ---------------------------------------
    def rigorous_part(self) -> SceneModel | None:
        """The composite of the block's rigorous scenes (None: RPC images only)."""
        return self.rigorous

    def rpc_images(self) -> list[RpcScene]:
        """The block's RPC images, in block order."""
        return list(self.images.values())

    def block_members(self) -> list[str]:
        """The block's scene names, in order."""
        return list(self.order)

    def answer(self, question):
        """``question.block(self)``."""
        return question.block(self)


def compose_mixed(scenes: dict) -> SceneModel | MixedBlock:
    """The block ``scenes`` (name -> SceneModel or RpcScene, in order) as one scene: the rigorous
    scenes' composite (:func:`core.model.block.compose_block`) when they are all rigorous, else a
    :class:`MixedBlock` of that composite (None without rigorous scenes) and the RPC images, each
    scene giving its own parts (:mod:`core.model.kinds`). InputError naming the scene for a name
    that is empty or holds '/', a scene listed twice, rigorous scenes that disagree on their
    corrections."""
    check_scene_names(scenes)
    rigorous = {n: s.rigorous_part() for n, s in scenes.items() if s.rigorous_part() is not None}
    rpc = {n: img for n, s in scenes.items() for img in s.rpc_images()}
    if not rpc:
        return compose_block(rigorous)
    composite = compose_block(rigorous) if rigorous else None
    images = {n: RpcScene(s.rpc, replace(s.camera, name=block_camera(n, s.camera.name)), s.correction.copy(),
                          dict(s.info)) for n, s in rpc.items()}
    return MixedBlock(composite, images, list(scenes))


class _Split:
    """The scenes of each kind of block composite (asked through ``answer``, core.model.kinds)."""

    rigorous = staticmethod(split_block)

    def block(self, scene: MixedBlock) -> dict:
        return scene.split()

    def rpc(self, scene: RpcScene) -> dict:
        raise ValueError("an RPC scene is not a block's composite: it has no scenes to split into")


def split_scenes(composite: SceneModel | MixedBlock) -> dict:
    """The scenes of a block's composite (:func:`compose_mixed`), name -> scene in block order:
    :func:`core.model.block.split_block` of a rigorous composite, :meth:`MixedBlock.split`."""
    return composite.answer(_Split())
