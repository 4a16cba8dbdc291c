#!/usr/bin/env python3
"""Check a kinescan LAS file with laspy, an independent reader (conventions §7).

Usage:
  python3 tests/laspy_check.py FILE.las --expect-epsg 32632 \
      --expect-dims sigma_x,sigma_y,sigma_z --expect-count 5000 [--expect-gps-time adjusted|week] \
      [--expect-shares share_a,share_b,...] [--expect-vertical "geoid.gtx height"]

Needs `pip install 'laspy[lazrs]' pyproj`. Exits non-zero, naming every failed check, if laspy
warns (warnings module or its logger), if the version is not 1.4 or the point format not 6, if
a named extra dimension is missing or not float, if parse_crs() does not give the EPSG code, if
the point count differs, if header bounds differ from the points', if legacy counts are not
zero, or if the GPS time type bit disagrees with the expectation or with the
stored times (week seconds must lie in [0, 604800]). With --expect-shares: each named dimension
must be a scaled integer that laspy decodes to fractions in [0, 1], and per point they must sum
to 1 within the storage rounding (half a step, 0.002, per dimension) or all be 0. With
--expect-vertical: the CRS must be compound, its horizontal part the EPSG code and its vertical
part a vertical CRS of that name (orthometric heights, output.geoid).
"""

import argparse
import logging
import struct
import sys
import warnings

SECONDS_PER_WEEK = 604800.0


class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(level=logging.WARNING)
        self.messages = []

    def emit(self, record):
        self.messages.append(f"laspy log {record.levelname}: {record.getMessage()}")


SHARE_STEP = 0.004


def check(path, epsg, dims, count, gps_time, shares=(), vertical=None):
    import laspy  # imported here so a missing package is reported as a failure, not a trace

    failures = []
    log = _Collect()
    logging.getLogger("laspy").addHandler(log)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        las = laspy.read(path)
        crs = las.header.parse_crs()
        extra = {d.name: d for d in las.point_format.extra_dimensions}
        _ = [las[name] for name in dims if name in extra]  # decode each requested dimension
        share_values = [las[name] for name in shares if name in extra]
        gps = las.gps_time if len(las.points) else None
    failures += [f"warning: {w.category.__name__}: {w.message}" for w in caught]
    failures += log.messages

    h = las.header
    if (h.version.major, h.version.minor) != (1, 4):
        failures.append(f"version {h.version}, expected 1.4")
    if las.point_format.id != 6:
        failures.append(f"point format {las.point_format.id}, expected 6")
    for name in dims:
        if name not in extra:
            failures.append(f"extra dimension {name!r} missing (have {sorted(extra)})")
        elif extra[name].kind.name != "FloatingPoint":
            failures.append(f"extra dimension {name!r} is {extra[name].dtype}, expected float")
    for name in shares:
        if name not in extra:
            failures.append(f"share dimension {name!r} missing (have {sorted(extra)})")
        elif extra[name].scales is None or extra[name].scales[0] != SHARE_STEP:
            failures.append(f"share dimension {name!r} has scale {extra[name].scales}")
    if shares and len(share_values) == len(shares) and len(las.points):
        import numpy as np

        v = np.stack([np.asarray(a, dtype=float) for a in share_values])
        total = v.sum(axis=0)
        if not (v.min() >= 0 and v.max() <= 1 + 1e-9):  # NaN-proof (numpy min/max keep NaN)
            failures.append(f"shares outside [0, 1]: {v.min()}..{v.max()}")
        off = ~(np.abs(total - 1.0) <= len(shares) * SHARE_STEP / 2 + 1e-9)
        if np.any(off & (total != 0)):
            failures.append(f"{int(np.sum(off & (total != 0)))} points whose shares do not sum to 1")
    if crs is not None and vertical is not None:
        parts = crs.sub_crs_list if crs.is_compound else []
        if len(parts) != 2 or not parts[1].is_vertical or parts[1].name != vertical:
            failures.append(f"CRS is not compound with the vertical CRS {vertical!r}: {crs.name}")
        else:
            crs = parts[0]
    if crs is None:
        failures.append("parse_crs() found no CRS")
    elif crs.to_epsg() != epsg:
        failures.append(f"parse_crs() gives EPSG {crs.to_epsg()}, expected {epsg}")
    if count is not None and (h.point_count != count or len(las.points) != count):
        failures.append(f"{h.point_count} points in header, {len(las.points)} read, expected {count}")

    if len(las.points):
        for axis, lo, hi in (("x", h.mins[0], h.maxs[0]), ("y", h.mins[1], h.maxs[1]),
                             ("z", h.mins[2], h.maxs[2])):
            v = getattr(las, axis)
            if not (abs(v.min() - lo) <= 1e-9 and abs(v.max() - hi) <= 1e-9):
                failures.append(f"header {axis} bounds {lo}..{hi}, points {v.min()}..{v.max()}")
    with open(path, "rb") as f:
        legacy = struct.unpack_from("<6I", f.read(131), 107)
    if any(legacy):
        failures.append(f"legacy point counts {legacy} must be zero for point format 6")

    adjusted = h.global_encoding.gps_time_type == laspy.header.GpsTimeType.STANDARD
    if gps_time is not None and adjusted != (gps_time == "adjusted"):
        failures.append(f"GPS time type bit is {int(adjusted)}, expected {gps_time}")
    if gps is not None and not adjusted and (gps.min() < 0 or gps.max() > SECONDS_PER_WEEK):
        failures.append(f"GPS time type bit clear but times {gps.min()}..{gps.max()} s")
    return failures


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--expect-epsg", type=int, required=True)
    ap.add_argument("--expect-dims", default="", help="comma-separated extra dimension names")
    ap.add_argument("--expect-count", type=int)
    ap.add_argument("--expect-gps-time", choices=["adjusted", "week"])
    ap.add_argument("--expect-shares", default="", help="comma-separated share dimension names")
    ap.add_argument("--expect-vertical", help="name of the vertical CRS of a compound CRS")
    args = ap.parse_args()
    dims = [d for d in args.expect_dims.split(",") if d]
    shares = [d for d in args.expect_shares.split(",") if d]
    try:
        failures = check(args.file, args.expect_epsg, dims, args.expect_count,
                         args.expect_gps_time, shares, args.expect_vertical)
    except Exception as e:  # noqa: BLE001 - any reader failure is a check failure
        failures = [f"{type(e).__name__}: {e}"]
    for f in failures:
        print(f"laspy_check: {args.file}: FAIL {f}", file=sys.stderr)
    if failures:
        sys.exit(1)
    print(f"laspy_check: {args.file}: OK (EPSG {args.expect_epsg}, dims {','.join(dims)})")


if __name__ == "__main__":
    main()
