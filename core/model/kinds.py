"""What a scene answers about its own kind, so that no code asks which kind it holds.

Three kinds of scene take part in an adjustment: a rigorous scene (:class:`core.model.sensor.
SceneModel`, a block's composite of rigorous scenes too), an RPC scene (:class:`core.model.rpcscene.
RpcScene`) and a block with RPC images (:class:`core.model.mixedblock.MixedBlock`). A scene is a
block of one. Each kind answers, as methods of its own:

- ``rigorous_part()``: the rigorous scene (or composite) it holds, None without one;
- ``rpc_images()``: the RPC images it holds (a list, empty without one);
- ``block_members()``: the names of the block's scenes ([] for a scene on its own);
- ``answer(question)``: the answer of ``question`` for its kind, ``question.rigorous(scene)``,
  ``question.rpc(scene)`` or ``question.block(scene)``: how a layer above the model (the adjustment's
  problem, the written scene) gives each kind its own behaviour without a type test.

:class:`RigorousKind` holds the rigorous scene's answers; the other kinds define theirs.
"""
from __future__ import annotations

BLOCK_KEY = "block"  # composite.info[BLOCK_KEY]: {scene name: {"epoch", "cameras", "info"}}


class RigorousKind:
    """The answers of a rigorous scene (see the module docstring); it has ``info``."""

    def rigorous_part(self):
        """The scene itself: it is all rigorous."""
        return self

    def rpc_images(self) -> list:
        """None: a rigorous scene holds no RPC image."""
        return []

    def block_members(self) -> list[str]:
        """The names of the scenes of a block's composite (:func:`core.model.block.compose_block`),
        [] for a scene on its own."""
        return list(self.info.get(BLOCK_KEY, {}))

    def answer(self, question):
        """``question.rigorous(self)``."""
        return question.rigorous(self)
