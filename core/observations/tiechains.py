"""Multi-image tie points chained from pairwise matches (union-find on the observations).

Each overlapping pair of images of a block is matched on its own (:class:`PairTies`: one tie is
one position in each of the two images). A ground point seen by k images is then found in up to
k(k-1)/2 pairs; :func:`chain_pairs` joins them into one tie point observed once per image. The
nodes are the observations (one image, one position, GDAL px); a tie links its two nodes, and
two nodes of one image closer than ``tolerance_px`` are one observation. A connected component
of that graph (scipy.sparse.csgraph.connected_components, the union-find of all nodes at once)
is a chain: one ground point. A chain whose nodes in one image lie further apart than
``tolerance_px`` (the extent of their positions, px) ties two ground points together through some
mismatch; it is refused whole, counted, and its ties are counted against the pairs that gave them.

The result does not depend on the order the pairs are given in (nodes are put in one order of
their image and position first): pairs matched by other processes or machines, returned in any
order, chain to the same table to the bit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import InputError
from .tiepoints import TieTable

CHAIN_TOLERANCE_PX = 1.0  # px: one image's observations of a chain closer than this are one


@dataclass(frozen=True)
class PairTies:
    """The ties matched between two images: ``first`` and ``second`` name each image as (scene,
    camera); per tie (m,): col_a, row_a in the first image, col_b, row_b in the second (GDAL px),
    sigma_px (px, the match's sigma, given to both observations)."""
    first: tuple[str, str]
    second: tuple[str, str]
    col_a: np.ndarray
    row_a: np.ndarray
    col_b: np.ndarray
    row_b: np.ndarray
    sigma_px: np.ndarray

    def __len__(self) -> int:
        return int(np.size(self.col_a))


@dataclass(frozen=True)
class ChainResult:
    """The chained tie points: table (one observation per point and image, ids 'T1'...);
    inconsistent_chains: chains refused for two positions in one image further apart than the
    tolerance; refused_per_pair (p,): each pair's ties that were in a refused chain;
    points_by_rays: {number of images: number of points}."""
    table: TieTable
    inconsistent_chains: int
    refused_per_pair: np.ndarray
    points_by_rays: dict[int, int]


def chain_pairs(pairs: list[PairTies], tolerance_px: float = CHAIN_TOLERANCE_PX) -> ChainResult:
    """Chain the ties of ``pairs`` into multi-image tie points (see the module docstring).
    InputError for a pair of one image with itself or a tolerance that is not positive."""
    if not tolerance_px > 0:
        raise InputError(f"the chain tolerance must be a positive number of pixels, not {tolerance_px}",
                         parameter="tolerance_px")
    same = [f"{p.first[0]}/{p.first[1]}" for p in pairs if p.first == p.second]
    if same:
        raise InputError(f"{', '.join(same)} is paired with itself: a pair is two images", parameter="pairs")
    views = sorted({p.first for p in pairs} | {p.second for p in pairs})
    index = {v: k for k, v in enumerate(views)}
    sizes = np.array([len(p) for p in pairs], int)
    col, row, sigma = (np.concatenate([np.concatenate([getattr(p, a), getattr(p, b)]) for p in pairs]
                                      + [np.empty(0)]).astype(float)
                       for a, b in (("col_a", "col_b"), ("row_a", "row_b"), ("sigma_px", "sigma_px")))
    # nodes: per pair, its first image's ties, then its second's
    view = np.concatenate([np.concatenate([np.full(len(p), index[p.first]), np.full(len(p), index[p.second])])
                           for p in pairs] + [np.empty(0, int)]).astype(int)
    start = np.cumsum(2 * sizes) - 2 * sizes
    a = np.concatenate([s + np.arange(m) for s, m in zip(start, sizes)] + [np.empty(0, int)]).astype(int)
    b = a + np.repeat(sizes, sizes)
    pair_of_tie = np.repeat(np.arange(len(pairs)), sizes)
    # one order of the nodes whatever the pairs' order: by image, then position, then sigma
    order = np.lexsort((sigma, col, row, view))
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    view, col, row, sigma = view[order], col[order], row[order], sigma[order]
    a, b = rank[a], rank[b]
    near_a, near_b = _near_nodes(view, col, row, len(views), tolerance_px)
    chain = _components(view.size, np.concatenate([a, near_a]), np.concatenate([b, near_b]))
    _, first_of_group, group = np.unique(chain * len(views) + view, return_index=True, return_inverse=True)
    return _chained(views, view, col, row, sigma, chain, group, first_of_group, tolerance_px, a, pair_of_tie,
                    len(pairs))


def _near_nodes(view: np.ndarray, col: np.ndarray, row: np.ndarray, n_views: int,
                tolerance_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Node index pairs (e,) (e,) of one image closer than ``tolerance_px`` (px); the nodes
    sorted by image (``view`` ascending), so each image's are one slice."""
    bounds = np.searchsorted(view, np.arange(n_views + 1))
    found = [np.empty((0, 2), int)]
    for start, end in zip(bounds[:-1], bounds[1:]):
        tree = cKDTree(np.column_stack([col[start:end], row[start:end]]))
        found.append(start + tree.query_pairs(tolerance_px, output_type="ndarray").reshape(-1, 2))
    both = np.concatenate(found)
    return both[:, 0], both[:, 1]


def _components(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Component (n,) of each node of the graph of edges a-b, numbered in order of their first node."""
    _, labels = connected_components(coo_matrix((np.ones(a.size), (a, b)), shape=(n, n)), directed=False)
    _, first = np.unique(labels, return_index=True)       # each label's first node
    return np.argsort(np.argsort(first))[labels]


def _chained(views, view, col, row, sigma, chain, group, first_of_group, tolerance_px, a, pair_of_tie,
             n_pairs) -> ChainResult:
    """The table of the consistent chains: one observation per (chain, image) group, at the
    mean of its nodes' positions and sigmas."""
    n_groups = first_of_group.size
    count = np.bincount(group, minlength=n_groups)

    def mean(values):
        return np.bincount(group, values, minlength=n_groups) / count

    by_group = np.argsort(group, kind="stable")
    starts = np.searchsorted(group[by_group], np.arange(n_groups))

    def extent(values):
        ordered = values[by_group]
        return np.maximum.reduceat(ordered, starts) - np.minimum.reduceat(ordered, starts) if n_groups else ordered

    group_chain = chain[first_of_group]
    n_chains = int(chain.max(initial=-1)) + 1
    bad = np.zeros(n_chains, bool)
    bad[group_chain[np.hypot(extent(col), extent(row)) > tolerance_px]] = True
    rays = np.bincount(group_chain, minlength=n_chains)
    good = ~bad & (rays >= 2)
    keep = good[group_chain]
    point = np.cumsum(good) - 1                      # the kept chains numbered in order
    ids = np.char.add("T", (point[group_chain[keep]] + 1).astype(str))
    names = np.array(views, dtype=str).reshape(-1, 2)
    owner = view[first_of_group[keep]]
    table = TieTable(ids, names[owner, 1], mean(col)[keep], mean(row)[keep], mean(sigma)[keep], names[owner, 0])
    refused = np.bincount(pair_of_tie[bad[chain[a]]], minlength=n_pairs)
    histogram = np.bincount(rays[good])
    return ChainResult(table, int(bad.sum()), refused,
                       {int(k): int(c) for k, c in enumerate(histogram) if c})
