#!/usr/bin/env python3
"""EPSG-frame oracle for kinescan's tests/suite/epsg_frames.rs, computed with pyproj (PROJ).

    python3 make_epsg_oracle.py               # (re)write epsg_oracle.csv next to this file
    python3 make_epsg_oracle.py --check FILE  # regenerate in memory, compare with FILE

For each CRS a short simulated survey: a vehicle drives a 1.2 km curve near a place in the
CRS's area of use and scans points up to 40 m around it (seeded). Each row holds the vehicle's
and the point's WGS84 ECEF coordinates (m, printed to 0.1 um and used as printed), pyproj's
map coordinates of the point (EPSG:4978 -> the CRS: easting, northing in the CRS unit; Z is the
WGS84 ellipsoidal height, as PROJ passes it to a 2D projected CRS) and pyproj's Jacobian
d(map)/d(ECEF) by central differences of 1 m (truncation ~1e-14, rounding ~5e-10 relative),
horizontal rows converted to metres.

The CRS is built from the EPSG database (CRS.from_epsg); the transformation WGS84 -> CRS is
PROJ's choice for the area, with two exceptions where the EPSG database and the definition
kinescan uses (PROJ.4 string with +towgs84, from the crs-definitions table) name different
Helmert parameters: for them the oracle uses the stated Helmert (CRS.from_proj4 of the
definition below) and prints how far the EPSG database's own choice is.
"""

import argparse
import csv
import io
import math
import random
import sys
from pathlib import Path

from pyproj import CRS, Transformer

HERE = Path(__file__).resolve().parent
CSV_PATH = HERE / "epsg_oracle.csv"

# (EPSG code, projection class, lat_deg, lon_deg, h_m) of the survey's start.
SURVEYS = [
    (2154, "lambert_conformal", 48.85, 2.35, 60.0),
    (3034, "lambert_conformal", 50.0, 10.0, 300.0),
    (31370, "lambert_conformal", 50.85, 4.35, 90.0),
    (3112, "lambert_conformal", -33.87, 151.2, 40.0),
    (2263, "lambert_conformal_us_ft", 40.75, -73.98, 20.0),
    (2229, "lambert_conformal_us_ft", 34.05, -118.25, 100.0),
    (32632, "transverse_mercator", 48.1, 11.6, 520.0),
    (25832, "transverse_mercator", 50.1, 8.7, 150.0),
    (32719, "transverse_mercator", -33.45, -70.66, 560.0),
    (2193, "transverse_mercator", -41.29, 174.78, 30.0),
    (27700, "transverse_mercator", 51.5, -0.12, 50.0),
    (2180, "transverse_mercator", 52.23, 21.01, 130.0),
    (3006, "transverse_mercator", 59.33, 18.07, 40.0),
    (3067, "transverse_mercator", 60.17, 24.94, 35.0),
    (26918, "transverse_mercator", 40.7, -74.0, 10.0),
    (28992, "oblique_stereographic", 52.37, 4.9, 45.0),
    (3031, "polar_stereographic", -77.85, 166.67, 30.0),
    (3413, "polar_stereographic", 69.2, -51.1, 60.0),
    (3995, "polar_stereographic", 78.22, 15.65, 40.0),
    (5070, "albers", 39.74, -104.99, 1600.0),
    (3577, "albers", -35.28, 149.13, 600.0),
    (3035, "lambert_azimuthal", 52.52, 13.4, 80.0),
    (2056, "oblique_mercator_swiss", 46.95, 7.45, 600.0),
    (3395, "mercator", 1.3, 103.8, 20.0),
    (6933, "cylindrical_equal_area", 30.0, 31.2, 70.0),
]
# The stated Helmert where the EPSG database's choice differs from it (see module doc).
STATED_HELMERT = {
    28992: "+proj=sterea +lat_0=52.15616055555555 +lon_0=5.38763888888889 +k=0.9999079 "
           "+x_0=155000 +y_0=463000 +ellps=bessel "
           "+towgs84=565.2369,50.0087,465.658,-0.406857,0.350733,-1.87035,4.0812 +units=m +no_defs",
}
POINTS_PER_SURVEY = 60
COLUMNS = ["code", "class", "i", "veh_x", "veh_y", "veh_z", "x", "y", "z", "easting",
           "northing", "height"] + [f"j{r}{c}" for r in range(3) for c in range(3)]
# --check: 1e-7 m printed resolution on coordinates, Jacobian printed to 1e-12.
CHECK_TOL = 2e-7


def crs_for(code):
    return CRS.from_proj4(STATED_HELMERT[code]) if code in STATED_HELMERT else CRS.from_epsg(code)


def survey(code, lat0, lon0, h0, rng, to_ecef):
    """(vehicle ECEF, point ECEF) pairs along a 1.2 km curve."""
    out = []
    heading = rng.uniform(0.0, 2.0 * math.pi)
    m_per_deg_lat = 111_000.0
    m_per_deg_lon = 111_000.0 * math.cos(math.radians(lat0))
    for i in range(POINTS_PER_SURVEY):
        s = 1200.0 * i / (POINTS_PER_SURVEY - 1)
        turn = heading + s / 800.0
        north = s * math.cos(turn)
        east = s * math.sin(turn)
        vlat, vlon = lat0 + north / m_per_deg_lat, lon0 + east / m_per_deg_lon
        vh = h0 + 2.0
        plat = vlat + rng.uniform(-40.0, 40.0) / m_per_deg_lat
        plon = vlon + rng.uniform(-40.0, 40.0) / m_per_deg_lon
        ph = h0 + rng.uniform(-3.0, 25.0)
        veh = [round(v, 7) for v in to_ecef.transform(vlon, vlat, vh)]
        pt = [round(v, 7) for v in to_ecef.transform(plon, plat, ph)]
        out.append((veh, pt))
    return out


def generate():
    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    rng = random.Random(20261123)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for code, cls, lat0, lon0, h0 in SURVEYS:
        crs = crs_for(code)
        metres = crs.axis_info[0].unit_conversion_factor
        fwd = Transformer.from_crs("EPSG:4978", crs, always_xy=True)

        def f(p):
            e, n, h = fwd.transform(*p)
            return [e, n, h]

        for i, (veh, pt) in enumerate(survey(code, lat0, lon0, h0, rng, to_ecef)):
            e, n, h = f(pt)
            jac = [[0.0] * 3 for _ in range(3)]
            for c in range(3):
                hi, lo = list(pt), list(pt)
                hi[c] += 1.0
                lo[c] -= 1.0
                fh, fl = f(hi), f(lo)
                for r in range(3):
                    jac[r][c] = (fh[r] - fl[r]) / 2.0 * (metres if r < 2 else 1.0)
            w.writerow([code, cls, i] + [f"{v:.7f}" for v in veh + pt]
                       + [f"{e:.7f}", f"{n:.7f}", f"{h:.7f}"]
                       + [f"{jac[r][c]:.12e}" for r in range(3) for c in range(3)])
    return buf.getvalue()


def epsg_database_differences():
    """Largest horizontal difference (m) between the stated Helmert and the EPSG database's
    own transformation, per CRS in STATED_HELMERT."""
    out = {}
    for code in STATED_HELMERT:
        lat0, lon0 = next((s[2], s[3]) for s in SURVEYS if s[0] == code)
        a = Transformer.from_crs("EPSG:4979", CRS.from_epsg(code), always_xy=True)
        b = Transformer.from_crs("EPSG:4979", crs_for(code), always_xy=True)
        pa, pb = a.transform(lon0, lat0, 0.0), b.transform(lon0, lat0, 0.0)
        out[code] = math.hypot(pa[0] - pb[0], pa[1] - pb[1])
    return out


def check(path):
    new = list(csv.DictReader(io.StringIO(generate())))
    old = list(csv.DictReader(open(path)))
    if len(new) != len(old):
        print(f"{path}: {len(old)} rows, pyproj gives {len(new)}")
        return 1
    worst = 0.0
    for a, b in zip(new, old):
        for k in COLUMNS[3:]:
            worst = max(worst, abs(float(a[k]) - float(b[k])))
            if not abs(float(a[k]) - float(b[k])) <= CHECK_TOL:
                print(f"{path}: code {a['code']} point {a['i']} {k}: pyproj {a[k]}, file {b[k]}")
                return 1
    for code, d in epsg_database_differences().items():
        print(f"EPSG:{code}: stated Helmert vs EPSG database transformation: {d * 1000:.1f} mm")
    print(f"{path}: {len(new)} rows agree with pyproj "
          f"(largest difference {worst:.1e})")
    return 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--check", type=Path)
    a = ap.parse_args()
    if a.check:
        sys.exit(check(a.check))
    CSV_PATH.write_text(generate())
    print(f"wrote {CSV_PATH}")


if __name__ == "__main__":
    main()
