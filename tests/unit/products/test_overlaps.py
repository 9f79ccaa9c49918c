"""The overlap graph of a block (core.products.overlaps): pairs and their geodesic overlap areas
against boxes of known area, connected components, products of other ground and disconnected
blocks refused naming them, and a tri-stereo's cameras outlined as one product."""
import numpy as np
import pytest
from pyproj import Geod

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.products.overlaps import (Outline, disconnection, meeting_boxes, overlap_graph, product_outline,
                                                     refuse_disconnected, tied_graph)

GEOD = Geod(ellps="WGS84")


def box(name, lon0, lon1, lat0=0.0, lat1=1.0, samples=50) -> Outline:
    """A lon/lat box densified along its edges (as footprints are), counter-clockwise."""
    t = np.linspace(0.0, 1.0, samples, endpoint=False)
    lon = np.concatenate([lon0 + (lon1 - lon0) * t, np.full(samples, lon1), lon1 - (lon1 - lon0) * t,
                          np.full(samples, lon0), [lon0]])
    lat = np.concatenate([np.full(samples, lat0), lat0 + (lat1 - lat0) * t, np.full(samples, lat1),
                          lat1 - (lat1 - lat0) * t, [lat0]])
    return Outline(name, lon, lat)


def area_km2(o: Outline) -> float:
    return abs(GEOD.polygon_area_perimeter(o.lon, o.lat)[0]) / 1e6


def test_pairs_and_their_areas_of_a_strip_of_boxes():
    """A-B overlap by half a degree, B-C by 0.3°, A-C not at all; D 10° away; C-E only touch."""
    outlines = [box("A", 0.0, 1.0), box("B", 0.5, 1.5), box("C", 1.2, 2.0), box("D", 10.0, 11.0),
                box("E", 2.0, 3.0)]
    graph = overlap_graph(outlines)
    assert graph.pair_names() == [("A", "B"), ("B", "C")]
    expected = [area_km2(box("", 0.5, 1.0)), area_km2(box("", 1.2, 1.5))]
    assert expected[0] == pytest.approx(6154.2, abs=0.1)          # half of a 1° cell at the equator
    np.testing.assert_allclose(graph.area_km2, expected, rtol=1e-7)  # the same box, other vertices
    assert graph.isolated == ["D", "E"]
    assert graph.components() == [["A", "B", "C"], ["D"], ["E"]]
    assert overlap_graph(outlines, min_area_km2=4000.0).pair_names() == [("A", "B")]


def test_a_block_across_the_antimeridian_stays_whole():
    graph = overlap_graph([box("west", 179.5, 180.5), box("east", -179.8, -178.8)])
    assert graph.pair_names() == [("west", "east")]
    assert graph.area_km2[0] == pytest.approx(area_km2(box("", 0.2, 0.5)), rel=1e-7)


def test_other_ground_and_disconnected_strips_are_named():
    strips = [box("s1a", 0.0, 1.0), box("s1b", 0.8, 1.8), box("s2a", 0.0, 1.0, 2.0, 3.0),
              box("s2b", 0.8, 1.8, 2.0, 3.0), box("far", 30.0, 31.0)]
    graph = overlap_graph(strips)
    np.testing.assert_array_equal(graph.component, [0, 0, 1, 1, 2])
    with pytest.raises(InputError, match=r"far overlaps no other product .*the others fall in 2 groups that do not "
                                         r"overlap each other: \(s1a, s1b\); \(s2a, s2b\)") as e:
        refuse_disconnected(graph)
    assert e.value.parameter == "scenes"
    joined = overlap_graph(strips[:4] + [box("bridge", 0.5, 1.5, 0.9, 2.1)])
    refuse_disconnected(joined)                                    # one block: nothing said
    assert len(joined.pairs) == 2 + 4 and joined.isolated == []


def test_pairs_that_gave_no_ties_can_cut_a_connected_block():
    graph = overlap_graph([box("a", 0.0, 1.0), box("b", 0.8, 1.8), box("c", 1.6, 2.6), box("d", 2.4, 3.4)])
    assert graph.pair_names() == [("a", "b"), ("b", "c"), ("c", "d")] and disconnection(graph) == ""
    cut = tied_graph(graph, np.array([True, False, True]))
    assert cut.pair_names() == [("a", "b"), ("c", "d")]
    np.testing.assert_allclose(cut.area_km2, graph.area_km2[[0, 2]])
    assert disconnection(cut) == "the others fall in 2 groups that do not overlap each other: (a, b); (c, d)"
    assert disconnection(tied_graph(graph, np.array([False, True, True]))) == "a overlaps no other product (other ground?)"


def test_a_products_cameras_outline_it_as_one():
    fwd, nad, bwd = box("", 0.0, 1.0, 0.0, 1.0), box("", 0.0, 1.0, 0.2, 1.2), box("", 0.0, 1.0, 0.4, 1.4)
    outline = product_outline("tlc", [fwd.lon, nad.lon, bwd.lon], [fwd.lat, nad.lat, bwd.lat])
    assert area_km2(outline) == pytest.approx(area_km2(box("", 0.0, 1.0, 0.0, 1.4)), rel=1e-6)
    with pytest.raises(InputError, match="tlc: the footprints of its cameras do not overlap"):
        product_outline("tlc", [fwd.lon, fwd.lon + 5], [fwd.lat, fwd.lat])


def test_names_given_twice_are_refused():
    with pytest.raises(InputError, match="A listed twice"):
        overlap_graph([box("A", 0.0, 1.0), box("A", 0.5, 1.5)])


def brute_force(boxes: np.ndarray) -> list[tuple[int, int]]:
    return [(i, j) for i in range(len(boxes)) for j in range(i + 1, len(boxes))
            if boxes[i, 0] < boxes[j, 2] and boxes[j, 0] < boxes[i, 2] and boxes[i, 1] < boxes[j, 3]
            and boxes[j, 1] < boxes[i, 3]]


def test_the_sweep_finds_exactly_the_boxes_that_meet():
    """A region's grid of 3 strips x 4 products (20 % side-lap, 15 % forward: each meets its 8
    neighbours, 29 pairs), boxes that only touch (no pair), equal left edges, and 300 random boxes:
    the sweep gives the all-pairs test's pairs, in its order."""
    w, h = 100.0, 100.0
    region = np.array([(s * 0.8 * w, p * 0.85 * h, s * 0.8 * w + w, p * 0.85 * h + h)
                       for s in range(3) for p in range(4)])
    pairs = meeting_boxes(region)
    assert len(pairs) == 29 and [tuple(p) for p in pairs] == brute_force(region)
    touching = np.array([(0, 0, 10, 10), (10, 0, 20, 10), (0, 10, 10, 20), (0, 5, 10, 15), (0, 0, 10, 10)], float)
    assert [tuple(p) for p in meeting_boxes(touching)] == [(0, 3), (0, 4), (2, 3), (3, 4)] == brute_force(touching)
    rng = np.random.default_rng(3)
    corner = rng.uniform(0, 1000, (300, 2))
    boxes = np.hstack([corner, corner + rng.uniform(1, 80, (300, 2))])
    assert [tuple(p) for p in meeting_boxes(boxes)] == brute_force(boxes)
    assert meeting_boxes(np.zeros((0, 4))).shape == (0, 2) and meeting_boxes(boxes[:1]).shape == (0, 2)
