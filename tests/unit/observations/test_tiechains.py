"""Multi-image tie points chained from pairwise matches (core.observations.tiechains): three
images related by known shifts, matched pair by pair like the overlap graph's pair jobs; every
chain must be one ground point, the chain through a mismatch is refused and counted against its
pairs, and the table does not depend on the pairs' order."""
import numpy as np
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.observations.tiechains import PairTies, chain_pairs

A, B, C = ("a", "NAD"), ("b", "NAD"), ("c", "FWD")
SHIFT = {A: (0.0, 0.0), B: (100.0, -3.0), C: (200.0, 5.0)}    # ground = image + shift (px of ground)


def image(view, x, y):
    return x - SHIFT[view][0], y - SHIFT[view][1]


def pair(first, second, x, y, sigma=0.2) -> PairTies:
    """Ties of ground points (x, y) between two images, exact."""
    (ca, ra), (cb, rb) = image(first, x, y), image(second, x, y)
    return PairTies(first, second, ca, ra, cb, rb, np.full(np.size(x), sigma))


def block() -> list[PairTies]:
    """a's grid (every 20 px) matched in b and c, b's own grid matched in c, and two ties of b's
    grid that land on a's matched points in b: one whose c position agrees (0.1 px), one 4 px off
    (a mismatch: its chain holds two positions in c 4 px apart)."""
    x, y = (v.ravel() for v in np.meshgrid(10.0 + 20 * np.arange(20), 10.0 + 20 * np.arange(5)))
    ab, ac = pair(A, B, x[x > 100], y[x > 100]), pair(A, C, x[x > 200], y[x > 200])
    bx, by = (v.ravel() for v in np.meshgrid(105.0 + 20 * np.arange(10), 5.0 + 20 * np.arange(5)))
    bc = pair(B, C, *(np.array(v) for v in (bx + 100, by - 3)))
    extra = PairTies(B, C, np.array([150.3, 170.2]), np.array([52.8, 73.1]), np.array([50.1, 74.0]),
                     np.array([45.0, 65.0]), np.array([0.4, 0.4]))
    bc = PairTies(B, C, *(np.concatenate([getattr(bc, f), getattr(extra, f)])
                          for f in ("col_a", "row_a", "col_b", "row_b", "sigma_px")))
    return [ab, ac, bc]


def test_pairs_chain_into_points_of_two_and_three_images():
    result = chain_pairs(block())
    t = result.table
    assert result.points_by_rays == {2: 25 + 50, 3: 49}            # a-b only, b's grid in c; a-b-c
    assert result.inconsistent_chains == 1
    np.testing.assert_array_equal(result.refused_per_pair, [1, 1, 1])
    assert len(t) == 25 * 2 + 49 * 3 + 50 * 2
    # each point one ground point, seen once per image
    shift = np.array([SHIFT[(s, c)] for s, c in zip(t.scene, t.camera)])
    ids, point = t.points()
    for k, coordinate in enumerate((t.col, t.row)):
        ground = coordinate + shift[:, k]
        spread = np.bincount(point, ground ** 2) / np.bincount(point) - (np.bincount(point, ground)
                                                                          / np.bincount(point)) ** 2
        assert spread.max() < 0.05                                  # px², the merged tie 0.3 px off
    key = np.char.add(np.char.add(t.id, "|"), t.scene)
    assert np.unique(key).size == len(t)
    # the agreeing tie merged into a's point (250, 50): b at the mean of 150, 150.3; c of 50, 50.1
    merged = t.id[(t.scene == "a") & (t.col == 250.0) & (t.row == 50.0)][0]
    mine = t.id == merged
    np.testing.assert_allclose(np.column_stack([t.col[mine], t.row[mine]]),
                               [[250.0, 50.0], [150.15, 52.9], [50.05, 45.0]])
    np.testing.assert_allclose(t.sigma_px[mine], [0.2, 0.3, 0.3])
    # the mismatched chain (a's point (270, 70)) is gone from every image
    assert not ((t.scene == "a") & (t.col == 270.0) & (t.row == 70.0)).any()
    assert not ((t.scene == "c") & (np.abs(t.col - 70.0) < 5) & (t.row == 65.0)).any()


def test_the_table_does_not_depend_on_the_pairs_order():
    pairs = block()
    swapped = [PairTies(p.second, p.first, p.col_b, p.row_b, p.col_a, p.row_a, p.sigma_px) for p in pairs[::-1]]
    one, other = chain_pairs(pairs).table, chain_pairs(swapped).table
    for name in one.ARRAYS:
        np.testing.assert_array_equal(getattr(one, name), getattr(other, name))
    np.testing.assert_array_equal(chain_pairs(swapped).refused_per_pair, [1, 1, 1])


def test_a_tighter_tolerance_refuses_the_agreeing_tie_instead():
    """At 0.2 px the agreeing tie is 0.36 px from a's point in b (two positions: refused) but
    0.1 px from it in c (linked); the mismatch, 0.22 px off in b, is no longer linked: a point of
    its own (b-c), and a's point (270, 70) keeps its three images."""
    result = chain_pairs(block(), tolerance_px=0.2)
    assert result.inconsistent_chains == 1
    np.testing.assert_array_equal(result.refused_per_pair, [1, 1, 1])
    assert result.points_by_rays == {2: 25 + 51, 3: 49}
    t = result.table
    assert ((t.scene == "a") & (t.col == 270.0) & (t.row == 70.0)).any()
    assert not ((t.scene == "a") & (t.col == 250.0) & (t.row == 50.0)).any()


def test_bad_pairs_are_refused():
    with pytest.raises(InputError, match="a/NAD is paired with itself"):
        chain_pairs([pair(A, A, np.array([1.0]), np.array([2.0]))])
    with pytest.raises(InputError, match="positive number of pixels"):
        chain_pairs(block(), tolerance_px=0.0)
    assert len(chain_pairs([]).table) == 0
