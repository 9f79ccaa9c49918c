"""core.observations.tables: the shared readers of point tables."""
import numpy as np
import pytest

from pushbroom_adjust.core.observations.tables import stripped


@pytest.mark.parametrize("cells", [
    [" a", "b", "c"], ["a", "b\t", "c"], ["a", "b", "c\u3000"], ["\u00a0a", "b"],  # leading, trailing, Unicode spaces
    ["a b", "c"], ["", "  ", "x"], ["é", "ü "],
])
def test_stripped_is_str_strip_of_every_cell(cells):
    assert stripped(cells).tolist() == [c.strip() for c in cells]


def test_stripped_keeps_cells_without_whitespace_and_reads_columns_of_a_table():
    table = np.array([["P1", " 3.5"], ["P22", "4 "]])
    assert stripped(table[:, 0]).tolist() == ["P1", "P22"]  # a strided column
    assert stripped(table[:, 1]).tolist() == ["3.5", "4"]
    assert stripped([]).shape == (0,) and stripped([""]).tolist() == [""]
