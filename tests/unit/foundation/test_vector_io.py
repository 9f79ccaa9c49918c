"""core.vector_io.write_layer: a layer of WKT points and plain columns (appended through an in-memory
CSV, core.vector_io.CSV_ROWS rows at a time) reads back exactly as written: strings with quotes, commas,
newlines and none at all; integers and booleans; floats to the bit, NaN as NULL; empty points."""
from __future__ import annotations

import numpy as np
import pytest
from osgeo import ogr

from pushbroom_adjust.core import vector_io
from pushbroom_adjust.core.observations.tiepoints import point_wkt
from pushbroom_adjust.core.vector_io import wgs84_3d, write_layer


@pytest.mark.parametrize("rows", [5, 100_000])
def test_a_layer_of_wkt_points_reads_back_exactly(tmp_path, monkeypatch, rows):
    monkeypatch.setattr(vector_io, "CSV_ROWS", 3 if rows == 5 else vector_io.CSV_ROWS)  # several chunks
    rng = np.random.default_rng(7)
    names = np.array(['a,"b"', "x\ny", "", "plain", "é ü"] * (rows // 5))
    real = rng.normal(size=rows) * 10.0 ** rng.integers(-300, 300, rows)
    real[::4] = np.nan
    count = rng.integers(-2 ** 31, 2 ** 31, rows)  # OGR's Integer fields: 32 bits
    flag = rng.random(rows) < 0.5
    lon, lat, h = rng.uniform(-180, 180, rows), rng.uniform(-90, 90, rows), rng.normal(0, 1000, rows)
    h[1::7] = np.nan  # no ground: POINT Z EMPTY
    path = tmp_path / "layer.gpkg"
    write_layer(path, "points", wgs84_3d(), ogr.wkbPoint25D, {"name": names, "real": real, "count": count,
                                                              "flag": flag}, point_wkt(lon, lat, h), {"KEY": "value"})
    ds = ogr.Open(str(path))
    layer = ds.GetLayer("points")
    assert layer.GetFeatureCount() == rows and layer.GetMetadataItem("KEY") == "value"
    got = [(f.GetFID(), f.GetField("name"), f.GetField("real"), f.GetField("count"), f.GetField("flag"),
            point_of(f.GetGeometryRef())) for f in layer]
    assert [g[0] for g in got] == list(range(1, rows + 1))
    assert [g[1] for g in got] == names.tolist()
    assert all((g[2] is None) if np.isnan(r) else g[2] == r for g, r in zip(got, real))
    assert [g[3] for g in got] == count.tolist() and [g[4] for g in got] == flag.astype(int).tolist()
    assert [g[5] for g in got] == [None if np.isnan(z) else (x, y, z) for x, y, z in zip(lon, lat, h)]


def point_of(geometry) -> tuple[float, float, float] | None:
    """(x, y, z) of a point, None when it is empty (read while its feature lives)."""
    return None if geometry.IsEmpty() else (geometry.GetX(), geometry.GetY(), geometry.GetZ())
