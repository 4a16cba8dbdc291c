#!/usr/bin/env python3
"""A LAZ or COPC file holds the same points and dimensions as its LAS (read with laspy, lazrs).

    python3 tests/laz_check.py cloud.las cloud.laz [--copc]

Every standard and extra dimension of every point must be equal (COPC reorders points into
its octree: both files are then sorted by GPS time, which is unique per point, before the
comparison). The extra dimensions must have the same names and types; the CRS WKT the same.
With --copc the file must also open with laspy's CopcReader, hold every point in its
hierarchy and answer a sub-box query with exactly the LAS points inside the box. Exit status 1 on any difference.
"""

import argparse
import sys

import laspy
import numpy as np


def copc_queries(las, path):
    """CopcReader: the whole hierarchy holds every point; a query of a sub-box (the middle
    30%-60% of the points in x and y, all heights) returns exactly the LAS points inside it."""
    problems = []
    x, y, z = np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)
    lo = np.array([np.quantile(x, 0.3), np.quantile(y, 0.3), z.min()])
    hi = np.array([np.quantile(x, 0.6), np.quantile(y, 0.6), z.max()])
    with laspy.CopcReader.open(path) as r:
        n = len(r.query())
        if n != las.header.point_count:
            problems.append(f"CopcReader query gives {n} of {las.header.point_count} points")
        box = r.query(bounds=laspy.copc.Bounds(lo, hi))
    inside = (x >= lo[0]) & (x <= hi[0]) & (y >= lo[1]) & (y <= hi[1])
    want = np.sort(np.asarray(las.gps_time)[inside])
    got = np.sort(np.asarray(box.gps_time))
    if inside.sum() == 0 or not np.array_equal(got, want):
        problems.append(f"sub-box query: {len(got)} points, {inside.sum()} LAS points inside")
    return problems


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("las")
    ap.add_argument("compressed")
    ap.add_argument("--copc", action="store_true")
    a = ap.parse_args()
    las = laspy.read(a.las)
    other = laspy.read(a.compressed, laz_backend=laspy.LazBackend.Lazrs)
    problems = []
    if las.header.point_count != other.header.point_count:
        problems.append(f"{las.header.point_count} vs {other.header.point_count} points")
    extra = lambda f: [(d.name, str(d.dtype)) for d in f.point_format.extra_dimensions]
    if extra(las) != extra(other):
        problems.append(f"extra dimensions {extra(las)} vs {extra(other)}")
    if las.header.parse_crs() != other.header.parse_crs():
        problems.append("CRS differs")
    if not problems:
        order_a = np.argsort(las.gps_time, kind="stable") if a.copc else slice(None)
        order_b = np.argsort(other.gps_time, kind="stable") if a.copc else slice(None)
        for name in las.point_format.dimension_names:
            va, vb = np.asarray(las[name])[order_a], np.asarray(other[name])[order_b]
            if not np.array_equal(va, vb):
                problems.append(f"dimension {name} differs")
    if a.copc and not problems:
        problems += copc_queries(las, a.compressed)
    for p in problems:
        print(f"{a.compressed}: {p}")
    if problems:
        sys.exit(1)
    print(f"{a.compressed}: {las.header.point_count} points, "
          f"{len(list(las.point_format.dimension_names))} dimensions identical to {a.las}")


if __name__ == "__main__":
    main()
