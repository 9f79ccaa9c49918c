"""The overlap graph of a block: which products' footprints overlap, by how much, and which
groups of products the overlaps tie together.

Frames and units: outlines are geodetic WGS84 rings (longitude, latitude in degrees), as
:func:`core.products.footprint.footprints` traces them on the DEM through each product's model;
a product of several cameras is outlined by the union of its cameras' footprints. Intersections
are exact for the rings as given (straight edges in longitude and latitude, which the densely
sampled footprints make a fraction of a pixel from the true outline); areas are geodesic, in km².

A pair of products is an edge of the graph when their outlines overlap by more than a minimum
area; the graph's connected components are the blocks the ties can hold together. A product in
no pair (other ground) and a block in several components (strips that do not meet) cannot be
adjusted as one block: :func:`refuse_disconnected` names them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from osgeo import ogr
from pyproj import Geod
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import InputError

ogr.UseExceptions()

GEOD = Geod(ellps="WGS84")


@dataclass(frozen=True)
class Outline:
    """A product's ground outline: its name and a closed ring lon, lat (deg WGS84), (m,) each."""
    name: str
    lon: np.ndarray
    lat: np.ndarray


@dataclass(frozen=True)
class OverlapGraph:
    """The overlaps of ``names`` (k,): pairs (p, 2) int, indices into names with first < second,
    sorted; area_km2 (p,) the geodesic area of each pair's intersection; component (k,) int, the
    connected component of each product (0 for the component of names[0], then numbered in the
    order of their first product)."""
    names: tuple[str, ...]
    pairs: np.ndarray
    area_km2: np.ndarray
    component: np.ndarray

    @property
    def isolated(self) -> list[str]:
        """The products in no overlapping pair."""
        paired = np.zeros(len(self.names), bool)
        paired[self.pairs.ravel()] = True
        return [n for n, p in zip(self.names, paired) if not p]

    def components(self) -> list[list[str]]:
        """Each connected component's product names, in component order."""
        return [[n for n, c in zip(self.names, self.component) if c == k]
                for k in range(int(self.component.max(initial=-1)) + 1)]

    def pair_names(self) -> list[tuple[str, str]]:
        return [(self.names[a], self.names[b]) for a, b in self.pairs]


def product_outline(name: str, lon_rings: list[np.ndarray], lat_rings: list[np.ndarray]) -> Outline:
    """The outline of a product whose cameras' footprints are the rings (lon, lat deg, each
    (m_i,)): their union's exterior (a three-line scene's cameras overlap each other; the
    union of cameras that do not meet is refused, naming the product)."""
    union = ogr.Geometry(ogr.wkbMultiPolygon)
    for lon, lat in zip(lon_rings, lat_rings):
        union.AddGeometry(_polygon(lon, lat))
    merged = union.UnionCascaded()
    if merged.GetGeometryType() != ogr.wkbPolygon:
        raise InputError(f"{name}: the footprints of its cameras do not overlap each other: one product must "
                         "show one piece of ground", parameter="scenes")
    ring = np.array(merged.GetGeometryRef(0).GetPoints())[:, :2]
    return Outline(name, ring[:, 0], ring[:, 1])


def overlap_graph(outlines: list[Outline], min_area_km2: float = 0.0) -> OverlapGraph:
    """The overlap graph of ``outlines`` (names unique): every pair whose intersection exceeds
    ``min_area_km2`` (km²). Candidate pairs are those whose bounding boxes meet (a
    sweep, :func:`meeting_boxes`), then intersected exactly. Longitudes are taken continuous around the
    first outline's, so a block crossing ±180° stays whole."""
    names = [o.name for o in outlines]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"{', '.join(twice)} listed twice: give each product once", parameter="scenes")
    if not outlines:
        raise InputError("no product given", parameter="scenes")
    ref = float(outlines[0].lon[0])
    lons = [ref + (o.lon - ref + 180.0) % 360.0 - 180.0 for o in outlines]
    boxes = np.array([(lo.min(), o.lat.min(), lo.max(), o.lat.max()) for lo, o in zip(lons, outlines)])
    first, second = meeting_boxes(boxes).T   # boxes that only touch share no area: never a pair
    polygons = [_polygon(lo, o.lat) for lo, o in zip(lons, outlines)]
    area = np.array([intersection_area_km2(polygons[a], polygons[b]) for a, b in zip(first, second)], float)
    keep = area > min_area_km2
    pairs = np.column_stack([first[keep], second[keep]]).astype(int).reshape(-1, 2)
    return OverlapGraph(tuple(names), pairs, area[keep], _components(len(names), pairs))


def meeting_boxes(boxes: np.ndarray) -> np.ndarray:
    """(p, 2) int: the pairs (i, j), i < j, of ``boxes`` (n, 4: xmin, ymin, xmax, ymax) whose
    interiors intersect, sorted. Sort and sweep along x: each box is tested only against the
    boxes that start within its x extent (in a region of strips, its own strip's and its
    neighbours'), so the work grows with the pairs found, not with n²."""
    n = len(boxes)
    order = np.argsort(boxes[:, 0], kind="stable")
    starts = boxes[order, 0]
    ends = np.searchsorted(starts, boxes[order, 2], side="left")    # boxes starting before each one's end
    found = []
    for k in range(n):
        i, others = order[k], order[k + 1:ends[k]]
        meet = others[(boxes[others, 1] < boxes[i, 3]) & (boxes[i, 1] < boxes[others, 3])]
        found.append(np.column_stack([np.minimum(i, meet), np.maximum(i, meet)]))
    pairs = np.concatenate(found).astype(int) if found else np.zeros((0, 2), int)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def intersection_area_km2(a: ogr.Geometry, b: ogr.Geometry) -> float:
    """Geodesic area (km²) of the intersection of two lon/lat polygons (0 when they only touch)."""
    if not a.Intersects(b):
        return 0.0
    cut = a.Intersection(b)
    total = 0.0
    for part in _polygons_of(cut):
        for k in range(part.GetGeometryCount()):
            ring = np.array(part.GetGeometryRef(k).GetPoints())
            if ring.shape[0] < 4:
                continue
            area, _ = GEOD.polygon_area_perimeter(ring[:, 0], ring[:, 1])
            total += abs(area) * (1.0 if k == 0 else -1.0)       # holes (k > 0) taken out
    return total / 1e6


def disconnection(graph: OverlapGraph) -> str:
    """'' when the pairs of ``graph`` connect every product, else a sentence naming the products in
    no pair and, when the others fall in several groups, each group."""
    alone = graph.isolated
    groups = [g for g in graph.components() if len(g) > 1]
    words = []
    if alone:
        words.append(f"{', '.join(alone)} overlap{'s' * (len(alone) == 1)} no other product (other ground?)")
    if len(groups) > 1:
        words.append(f"the others fall in {len(groups)} groups that do not overlap each other: "
                     + "; ".join(f"({', '.join(g)})" for g in groups))
    return "; ".join(words)


def refuse_disconnected(graph: OverlapGraph) -> None:
    """InputError (parameter 'scenes') with :func:`disconnection`'s sentence when the overlaps do
    not connect every product: a block adjusts as one only then (one alone would be adjusted on
    its own prior, silently)."""
    words = disconnection(graph)
    if words:
        raise InputError(f"the block is not connected by overlaps: {words}. Leave them out, adjust each group as "
                         "its own block, or add the products between them", parameter="scenes")


def tied_graph(graph: OverlapGraph, tied: np.ndarray) -> OverlapGraph:
    """``graph`` with only the pairs where ``tied`` (p,) bool holds (e.g. the pairs that gave ties)."""
    pairs = graph.pairs[tied]
    return OverlapGraph(graph.names, pairs, graph.area_km2[tied], _components(len(graph.names), pairs))


def _polygon(lon: np.ndarray, lat: np.ndarray) -> ogr.Geometry:
    ring = ogr.Geometry(ogr.wkbLinearRing)
    for x, y in zip(np.asarray(lon, float), np.asarray(lat, float)):
        ring.AddPoint_2D(float(x), float(y))
    ring.CloseRings()
    polygon = ogr.Geometry(ogr.wkbPolygon)
    polygon.AddGeometry(ring)
    return polygon if polygon.IsValid() else polygon.Buffer(0)    # a ring crossing itself made valid


def _polygons_of(geometry: ogr.Geometry) -> list[ogr.Geometry]:
    """The polygons of an intersection (a polygon, a multipolygon or a collection with lines)."""
    kind = ogr.GT_Flatten(geometry.GetGeometryType())
    if kind == ogr.wkbPolygon:
        return [geometry]
    if kind in (ogr.wkbMultiPolygon, ogr.wkbGeometryCollection):
        return [p for k in range(geometry.GetGeometryCount()) for p in _polygons_of(geometry.GetGeometryRef(k))]
    return []


def _components(n: int, pairs: np.ndarray) -> np.ndarray:
    """Connected components (n,) of the graph of ``pairs``, numbered by their first node."""
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    _, first = np.unique(labels, return_index=True)       # each label's first product
    return np.argsort(np.argsort(first))[labels]
