#!/usr/bin/env python3
"""Geoid oracle for kinescan's geoid grids (tests/suite/geoid.rs), computed with pyproj (PROJ).

    python3 make_geoid_oracle.py               # (re)write the test grids and geoid_oracle.csv
    python3 make_geoid_oracle.py --check FILE  # regenerate in memory, compare with FILE and
                                               # with the committed grid files

The test grid is synthetic and small enough to commit: N(lat, lon) = 47.5 + 2.5 sin(3 lat)
cos(2 lon) + 0.04 (lat - 49) (lon - 9) m (lat, lon in degrees inside the trig in radians
scaled as written below), on 0.25 deg nodes over 47..51 N, 5..13 E (around the test suite's
synthetic drive near Munich), rounded to float32. It is written twice, byte for byte defined
here: as GTX (40-byte big-endian header + big-endian float32 rows south to north) and as a
one-strip uncompressed Float32 GeoTIFF (PixelIsArea, tie point at the north-west pixel corner,
EPSG:4326), the two formats PROJ reads. The CSV holds random and edge points with pyproj's
orthometric height H = h - N through PROJ's vgridshift on each file (PROJ's bilinear).
"""

import argparse
import csv
import io
import math
import random
import struct
import sys
from pathlib import Path

from pyproj import Transformer

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "data"
GTX_PATH = DATA / "geoid_test.gtx"
TIF_PATH = DATA / "geoid_test.tif"
CSV_PATH = HERE / "geoid_oracle.csv"
SOUTH, WEST, STEP, ROWS, COLS = 47.0, 5.0, 0.25, 17, 33
COLUMNS = ["lat_deg", "lon_deg", "h_m", "H_gtx_m", "H_tif_m"]
CHECK_TOL = 2e-7  # printed to 1e-7 m


def undulation(lat, lon):
    n = 47.5 + 2.5 * math.sin(math.radians(3 * lat)) * math.cos(math.radians(2 * lon)) \
        + 0.04 * (lat - 49.0) * (lon - 9.0)
    return struct.unpack(">f", struct.pack(">f", n))[0]


def grid_rows():
    """Rows south to north, west to east."""
    return [[undulation(SOUTH + r * STEP, WEST + c * STEP) for c in range(COLS)]
            for r in range(ROWS)]


def gtx_bytes():
    out = struct.pack(">ddddii", SOUTH, WEST, STEP, STEP, ROWS, COLS)
    for row in grid_rows():
        out += struct.pack(f">{COLS}f", *row)
    return out


def tif_bytes():
    rows = list(reversed(grid_rows()))  # north to south
    pixels = b"".join(struct.pack(f"<{COLS}f", *row) for row in rows)
    scale = struct.pack("<3d", STEP, STEP, 0.0)
    # PixelIsArea: the tie point is the north-west corner of the north-west pixel.
    north = SOUTH + STEP * (ROWS - 1)
    tie = struct.pack("<6d", 0.0, 0.0, 0.0, WEST - STEP / 2, north + STEP / 2, 0.0)
    keys = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326]
    geokeys = struct.pack(f"<{len(keys)}H", *keys)
    # Layout: header, IFD, then the arrays and the pixels.
    entries_n = 14
    ifd_size = 2 + entries_n * 12 + 4
    off = 8 + ifd_size
    blobs = []

    def blob(data):
        nonlocal off
        at = off
        blobs.append(data)
        off += len(data)
        return at

    scale_at, tie_at, keys_at = blob(scale), blob(tie), blob(geokeys)
    pix_at = blob(pixels)
    # (tag, type, count, value): type 3 SHORT, 4 LONG, 12 DOUBLE
    entries = [
        (256, 3, 1, COLS), (257, 3, 1, ROWS), (258, 3, 1, 32), (259, 3, 1, 1),
        (262, 3, 1, 1), (273, 4, 1, pix_at), (277, 3, 1, 1), (278, 3, 1, ROWS),
        (279, 4, 1, len(pixels)), (284, 3, 1, 1), (339, 3, 1, 3),
        (33550, 12, 3, scale_at), (33922, 12, 6, tie_at), (34735, 3, len(keys), keys_at),
    ]
    assert len(entries) == entries_n
    ifd = struct.pack("<H", entries_n)
    for tag, typ, count, value in entries:
        if typ == 3 and count == 1:
            ifd += struct.pack("<HHIHH", tag, typ, count, value, 0)
        else:
            ifd += struct.pack("<HHII", tag, typ, count, value)
    ifd += struct.pack("<I", 0)
    return b"II*\x00" + struct.pack("<I", 8) + ifd + b"".join(blobs)


def points():
    rng = random.Random(20261123)
    pts = [(round(rng.uniform(SOUTH, SOUTH + STEP * (ROWS - 1)), 9),
            round(rng.uniform(WEST, WEST + STEP * (COLS - 1)), 9),
            round(rng.uniform(-50.0, 3000.0), 4)) for _ in range(300)]
    # Nodes, cell edges and the grid's corners.
    pts += [(48.0, 9.0, 500.0), (48.125, 9.0, 10.0), (48.0, 9.125, 0.0), (47.0, 5.0, 100.0),
            (51.0, 13.0, 100.0), (47.0, 13.0, 0.0), (51.0, 5.0, 0.0), (48.137, 11.575, 520.0)]
    return pts


def generate(gtx, tif):
    def vgrid(path):
        return Transformer.from_pipeline(
            "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
            f"+step +proj=vgridshift +grids={path} +multiplier=-1 "
            "+step +proj=unitconvert +xy_in=rad +xy_out=deg")
    a, b = vgrid(gtx), vgrid(tif)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for lat, lon, h in points():
        ha = a.transform(lon, lat, h, errcheck=True)[2]
        hb = b.transform(lon, lat, h, errcheck=True)[2]
        w.writerow([f"{lat:.9f}", f"{lon:.9f}", f"{h:.4f}", f"{ha:.7f}", f"{hb:.7f}"])
    return buf.getvalue()


def check(path):
    if GTX_PATH.read_bytes() != gtx_bytes() or TIF_PATH.read_bytes() != tif_bytes():
        print("committed test grids differ from the ones this script writes")
        return 1
    new = list(csv.DictReader(io.StringIO(generate(GTX_PATH, TIF_PATH))))
    old = list(csv.DictReader(open(path)))
    worst = 0.0
    for a, b in zip(new, old):
        for k in COLUMNS:
            d = abs(float(a[k]) - float(b[k]))
            worst = max(worst, d)
            if not d <= CHECK_TOL:
                print(f"{path}: {k} at {a['lat_deg']}, {a['lon_deg']}: pyproj {a[k]}, file {b[k]}")
                return 1
    if len(new) != len(old):
        print(f"{path}: {len(old)} rows, pyproj gives {len(new)}")
        return 1
    # pyproj refuses a point outside the grid too (same extent rule as kinescan's).
    try:
        Transformer.from_pipeline(f"+proj=vgridshift +grids={GTX_PATH} +multiplier=-1") \
            .transform(math.radians(4.9), math.radians(48.0), 0.0, errcheck=True)
        print("pyproj accepted a point outside the grid")
        return 1
    except Exception:
        pass
    print(f"{path}: {len(new)} rows agree with pyproj (largest difference {worst:.1e} m)")
    return 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--check", type=Path)
    a = ap.parse_args()
    if a.check:
        sys.exit(check(a.check))
    DATA.mkdir(exist_ok=True)
    GTX_PATH.write_bytes(gtx_bytes())
    TIF_PATH.write_bytes(tif_bytes())
    CSV_PATH.write_text(generate(GTX_PATH, TIF_PATH))
    print(f"wrote {GTX_PATH}, {TIF_PATH}, {CSV_PATH}")


if __name__ == "__main__":
    main()
