"""The TOML writer: what it writes reads back with tomllib to the same document."""
import math
import tomllib

import numpy as np
import pytest

from contfab.toml_writer import dumps


def test_round_trip_nested_tables_scalars_arrays_and_quoted_keys():
    doc = {"tier": 2, "a": {"x": 1.5, "s": 'quote " and é', "flag": True, "arr": [1, 2.5, -3],
                            "big": 1e300, "tiny": 5e-324, "np": np.float64(0.1),
                            "sub": {"inf": math.inf, "bad key.x": -1}}, "empty": {}}
    back = tomllib.loads(dumps(doc, "a header\nof two lines"))
    doc["a"]["np"] = 0.1
    assert back == doc


def test_none_is_left_out_and_nan_kept_and_objects_refused():
    back = tomllib.loads(dumps({"t": {"v": None, "n": math.nan}}))
    assert "v" not in back["t"] and math.isnan(back["t"]["n"])
    with pytest.raises(TypeError, match="cannot write object"):
        dumps({"x": object()})
