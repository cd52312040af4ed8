#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Reads a btfkit HDF5 file with h5py exactly as docs/formats.md shows (run by src/btf/io/h5_test).

Usage: read_h5.py FILE VIEW LIGHT X Y
Prints one JSON object: the RGB value of texel (X, Y) in the image of view VIEW, light LIGHT,
both directions (theta, phi) in degrees, the dataset's shape and dtype, the view set's name and
the hdr flag.
"""
import json
import sys

path = sys.argv[1]
view, light, x, y = (int(a) for a in sys.argv[2:6])

# ---- the five lines of docs/formats.md ("Reading it with h5py") ----
import h5py, numpy as np
f = h5py.File(path, "r")
assert f.attrs["format"] == "btfkit-btf" and f.attrs["format_version"] == 1
views, lights = f["views"][:], f["lights"][:]  # [n, 2]: (theta, phi) in degrees
image = f["images"][view, light].astype(np.float32)  # [height, width, 3] linear RGB; texel (x, y) = image[y, x]
# ----

print(json.dumps({
    "rgb": [float(v) for v in image[y, x]],
    "view": [float(a) for a in views[view]],
    "light": [float(a) for a in lights[light]],
    "shape": list(f["images"].shape),
    "dtype": str(f["images"].dtype),
    "view_set": f["views"].attrs["name"],
    "hdr": bool(f.attrs["hdr"]),
}))
