#!/usr/bin/env python3
"""Geodesy oracle for kinescan's tests/geodesy.rs, computed with pyproj (PROJ).

    python3 make_geodesy_oracle.py               # (re)write geodesy_oracle.csv next to this file
    python3 make_geodesy_oracle.py --check FILE  # regenerate in memory, compare with FILE

For each point (geodetic WGS84 lat/lon in degrees, ellipsoidal height in m) the CSV holds:
ECEF x, y, z (EPSG:4979 -> EPSG:4978), and UTM easting/northing in the stated zone
(EPSG:4326 -> EPSG:326zz/327zz) with PROJ's meridian convergence (deg) and point scale factor.
Zones are the natural 6-degree zone except the "off-zone" rows, which are projected in a zone
whose central meridian is 6 deg away (3 deg beyond the zone edge).

--check also parses every WKT in wkt_samples.tsv (written by kinescan's MapFrame::wkt and
compared byte for byte by tests/geodesy.rs) and requires CRS.from_wkt(wkt).to_epsg() to be the
listed EPSG code (the geographic 4326, 4979 and 4258 included; or None for the local ENU frame;
"h+v" for a compound CRS: the horizontal and
vertical codes, "none" for a vertical CRS named after an unknown grid), read by pyproj and by
laspy's `parse_crs`, with no TOWGS84 node; every code of docs/output.md's accuracy table must
have a sample. Exit status 1 on any mismatch.
"""

import argparse
import csv
import io
import math
import random
import sys
from pathlib import Path

import pyproj
from pyproj import CRS, Proj, Transformer

HERE = Path(__file__).resolve().parent
CSV_PATH = HERE / "geodesy_oracle.csv"
WKT_PATH = HERE / "wkt_samples.tsv"
COLUMNS = [
    "id", "lat_deg", "lon_deg", "h_m", "x_m", "y_m", "z_m", "zone", "north",
    "easting_m", "northing_m", "convergence_deg", "scale",
]
# Printed resolution is 1e-7 m and 1e-12 deg/scale; --check tolerances sit above the last
# printed digit and far below the 0.1 mm the Rust tests require.
CHECK_TOL = {"x_m": 1e-6, "y_m": 1e-6, "z_m": 1e-6, "easting_m": 1e-6, "northing_m": 1e-6,
             "convergence_deg": 1e-10, "scale": 1e-10}
HEIGHTS_M = [-100.0, 0.0, 250.0, 1000.0, 4500.0, 9000.0]


def natural_zone(lon_deg):
    return min(int(math.floor(((lon_deg + 180.0) % 360.0) / 6.0)), 59) + 1


def points():
    """(lat_deg, lon_deg, h_m, zone or None for the natural zone)."""
    named = [
        (0.0, 3.0), (0.0, -177.0), (0.5, -78.5), (-0.5, -78.5), (1.3, 103.8),
        (19.4, -99.1), (30.0, -150.0), (35.7, 139.7), (40.7, -74.0), (48.1, 11.6),
        (52.5, 13.4), (60.2, 24.9), (64.1, -21.9), (71.0, 25.8), (79.9, 15.0),
        (-23.5, 133.0), (-33.9, 18.4), (-45.0, 170.0), (-66.0, 110.0), (-79.9, -60.0),
        # Within 1e-3 deg of a zone edge, on both sides.
        (45.0, 5.999), (45.0, 6.0), (-30.0, -120.0005), (-30.0, -119.9995),
        (10.0, 29.9999), (-10.0, 179.9995),
    ]
    out = [(lat, lon, HEIGHTS_M[i % len(HEIGHTS_M)], None) for i, (lat, lon) in enumerate(named)]
    # 3 deg beyond the zone edge: 6 deg from the central meridian of the stated zone.
    off = [(50.0, 15.0, 32), (-20.0, -63.0, 21), (70.0, 33.0, 35), (0.5, 129.0, 51),
           (80.0, -3.0, 31), (-55.0, -75.0, 19)]
    out += [(lat, lon, HEIGHTS_M[(i + 2) % len(HEIGHTS_M)], z) for i, (lat, lon, z) in enumerate(off)]
    rng = random.Random(20261121)
    for _ in range(24):
        lat = round(rng.uniform(-80.0, 80.0), 9)
        lon = round(rng.uniform(-180.0, 180.0), 9)
        out.append((lat, lon, round(rng.uniform(-100.0, 9000.0), 3), None))
    return out


def generate():
    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for i, (lat, lon, h, zone) in enumerate(points()):
        zone = zone or natural_zone(lon)
        north = lat >= 0.0
        epsg = (32600 if north else 32700) + zone
        x, y, z = to_ecef.transform(lon, lat, h)
        utm = Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True)
        e, n = utm.transform(lon, lat)
        fac = Proj(CRS.from_epsg(epsg)).get_factors(lon, lat)
        w.writerow([i, f"{lat:.9f}", f"{lon:.9f}", f"{h:.3f}", f"{x:.7f}", f"{y:.7f}",
                    f"{z:.7f}", zone, int(north), f"{e:.7f}", f"{n:.7f}",
                    f"{fac.meridian_convergence:.12f}", f"{fac.meridional_scale:.12f}"])
    return buf.getvalue()


def check_csv(fresh, committed_path):
    fresh_rows = list(csv.DictReader(io.StringIO(fresh)))
    with open(committed_path, newline="") as f:
        old_rows = list(csv.DictReader(f))
    errors = []
    if len(fresh_rows) != len(old_rows):
        errors.append(f"{len(old_rows)} rows committed, {len(fresh_rows)} regenerated")
    for a, b in zip(fresh_rows, old_rows):
        for col in COLUMNS:
            if col in CHECK_TOL:
                if not abs(float(a[col]) - float(b[col])) <= CHECK_TOL[col]:  # NaN fails
                    errors.append(f"row {b['id']} {col}: committed {b[col]}, pyproj {a[col]}")
            elif a[col] != b[col]:
                errors.append(f"row {b['id']} {col}: committed {b[col]}, regenerated {a[col]}")
    return errors


# Codes whose definition in the crs-definitions crate (an older EPSG export) differs from the
# EPSG database of PROJ 9.5, so PROJ matches them only at confidence 25 (name and authority):
# kinescan computes with the crate's definition and says so; the check still requires the
# code at that confidence.
OUTDATED_DEFINITIONS = {
    2180: "EPSG now defines 2180 on ETRF2000-PL (EPSG:9702); the crate has ETRS89 (EPSG:4258)",
    5514: "EPSG renamed the S-JTSK datum and rounds Krovak's parameters differently",
}


def docs_table_codes():
    """EPSG codes of docs/output.md's accuracy table (the `| class | CRSs |` rows)."""
    import re
    text = (HERE.parents[1] / "docs" / "output.md").read_text()
    table = text.split("| class | CRSs |", 1)[1].split("\n\n", 1)[0]
    codes = set()
    for row in table.splitlines()[2:]:
        cells = row.split("|")
        if len(cells) > 2:
            # "2154, 3034, 31370 (Int. 1924 + 7-param Helmert), 3112": each item's leading code.
            items = (re.match(r"\s*(\d{4,5})\b", item) for item in cells[2].split(","))
            codes.update(int(m.group(1)) for m in items if m)
    return codes


# The geographic outputs (X longitude, Y latitude in degrees; docs/output.md): each must have
# a sample (4326 also as the horizontal CRS of a compound one) that pyproj identifies.
GEOGRAPHIC_CODES = {4326, 4979, 4258}


def identify(wkt):
    """EPSG code (or codes "h+v" of a compound CRS) pyproj and laspy read from a WKT."""
    import laspy
    crs = CRS.from_wkt(wkt)
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(wkt))
    via_laspy = header.parse_crs()
    if crs.is_compound:
        h, v = crs.sub_crs_list
        vh, vv = via_laspy.sub_crs_list
        got = f"{h.to_epsg()}+{v.to_epsg() or 'none'}"
        return got, f"{vh.to_epsg()}+{vv.to_epsg() or 'none'}"
    return crs.to_epsg(), via_laspy.to_epsg()


def check_wkt():
    errors = []
    lines = WKT_PATH.read_text().splitlines()
    seen = set()
    for line in lines:
        expected, wkt = line.split("\t", 1)
        got, via_laspy = identify(wkt)
        if "+" in expected:
            want = expected
            seen.add(int(expected.split("+")[0]))
        else:
            want = None if expected == "none" else int(expected)
            if want is not None:
                seen.add(want)
            if want in OUTDATED_DEFINITIONS and got is None:
                got = via_laspy = CRS.from_wkt(wkt).to_epsg(min_confidence=25)
                print(f"EPSG:{want}: identified at confidence 25 only: "
                      f"{OUTDATED_DEFINITIONS[want]}")
        if got != want or via_laspy != want:
            errors.append(f"WKT for {expected}: pyproj to_epsg() gives {got}, "
                          f"laspy parse_crs() {via_laspy}")
        if "TOWGS84" in wkt:
            errors.append(f"WKT for {expected} has a TOWGS84 node (pyproj reads a BoundCRS)")
    missing = (docs_table_codes() | GEOGRAPHIC_CODES) - seen
    if missing:
        errors.append(f"codes of docs/output.md's table without a WKT sample: {sorted(missing)}")
    return errors, len(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", metavar="FILE", help="compare FILE with a fresh pyproj run")
    args = ap.parse_args()
    fresh = generate()
    if args.check is None:
        CSV_PATH.write_text(fresh)
        print(f"wrote {CSV_PATH} ({fresh.count(chr(10)) - 1} points)")
        return 0
    errors = check_csv(fresh, args.check)
    wkt_errors, n_wkt = check_wkt()
    errors += wkt_errors
    for e in errors:
        print(e, file=sys.stderr)
    if errors:
        return 1
    print(f"{args.check}: matches pyproj {pyproj.__version__} (PROJ {pyproj.proj_version_str});"
          f" {n_wkt} WKT samples identify as expected")
    return 0


if __name__ == "__main__":
    sys.exit(main())
