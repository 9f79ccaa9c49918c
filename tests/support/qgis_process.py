"""Running the plugin's algorithms through qgis_process (the ``qgis_process`` fixture of
tests/qgis/conftest.py) and reading the vector files they write."""
import json

import numpy as np
from osgeo import ogr


def run_json(qgis_process, alg, **params) -> dict:
    """Run algorithm ``alg`` with ``params`` (KEY=value; a list: KEY=value once per item, as
    multiple-layer parameters take them) through the ``qgis_process`` fixture's runner with
    --json; asserts exit code 0 and returns the run's "results"."""
    done = qgis_process("--json", "run", alg, "--", *(f"{k}={v}" for k, values in params.items()
                                                        for v in (values if isinstance(values, list) else [values])))
    assert done.returncode == 0, done.stdout + done.stderr
    return json.loads(done.stdout)["results"]


def read_layer(path, *fields):
    """(attributes (n, len(fields)), geometries as WKT) of the first layer of a vector file."""
    ds = ogr.Open(str(path))
    layer = ds.GetLayer(0)
    values, wkts = [], []
    for f in layer:
        values.append([f.GetField(n) for n in fields])
        wkts.append(f.GetGeometryRef().ExportToWkt())
    return np.array(values, dtype=object), wkts
