#!/usr/bin/env python3
"""Cramer-Rao bound of the tripod boresight calibration (docs/calibration.md), independent of
kinescan's estimator: the oracle for tests/calib_boresight.rs `estimator_attains_the_bound`.

    python3 boresight_crb.py          # prints the bound (1-sigma, deg, at 1 mm centre noise)
    python3 boresight_crb.py --check  # CI: the bounds calib_boresight.rs hard-codes are these

Model, from first principles (convention frames): tripod apex at the NED origin, legs
w_i = Rot(phi) e_i (60 deg off the vertical axis, azimuths a_i about it, the Rust simulator's
axis basis: leg = cos60 z + sin60 (cos a y - sin a x)); at site k the scanner frame maps to NED
by M_k = R_k Rz Ry Rx(d) R_nom, its optical centre is o_k + t_k, its scan plane is x_s = 0;
leg i is cut at s_i = m.o / m.w_i (m = M_k x_s) and the observed ellipse centre is the (y_s, z_s)
of M_k^T (s_i w_i - o_k); o_k puts beam beta = 0 through the axis cut_depth below the apex
(as the simulator does). Unknowns: misalignment d (3), tripod orientation phi (3), each site's
position t_k (3): 15, from 18 centre coordinates with iid noise sigma. The bound is
sigma^2 (J^T J)^-1 with J by central differences at the truth (the scenario's misalignment).
IMU attitudes are exact.
"""

import re
import sys
from pathlib import Path

import numpy as np

D2R = np.pi / 180.0


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def r_zyx(x, y, z):
    return rot_z(z) @ rot_y(y) @ rot_x(x)


def rotvec(v):
    th = np.linalg.norm(v)
    if th == 0.0:
        return np.eye(3)
    k = v / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * kx + (1 - np.cos(th)) * kx @ kx


def site_rotation(deg, order):
    r, p, h = np.asarray(deg) * D2R
    return r_zyx(r, p, h) if order == "zyx" else rot_x(r) @ rot_y(p) @ rot_z(h)


def bound_deg(sites_deg, order="zyx", azimuths_deg=(15, 135, 255), cut_depth_m=0.5,
              distance_m=1.0, sigma_m=1e-3, misalignment_deg=(0.5, -0.3, 1.0)):
    legs = [np.array([-np.sin(a * D2R) * np.sin(60 * D2R),
                      np.cos(a * D2R) * np.sin(60 * D2R), np.cos(60 * D2R)])
            for a in azimuths_deg]
    r_nom = r_zyx(0.0, -90 * D2R, 180 * D2R)
    d_true = np.asarray(misalignment_deg) * D2R
    rots = [site_rotation(s, order) for s in sites_deg]
    origins = [np.array([0, 0, cut_depth_m]) - (r @ r_zyx(*d_true) @ r_nom)[:, 2] * distance_m
               for r in rots]

    def centres(p):
        out = []
        for k, r in enumerate(rots):
            m_k = r @ r_zyx(*(d_true + p[:3])) @ r_nom
            o = origins[k] + p[6 + 3 * k:9 + 3 * k]
            for e in legs:
                w = rotvec(p[3:6]) @ e
                s = m_k[:, 0] @ o / (m_k[:, 0] @ w)
                c = m_k.T @ (s * w - o)
                out += [c[1], c[2]]
        return np.array(out)

    n = 6 + 3 * len(rots)
    h = 1e-6
    jac = np.column_stack([(centres(h * np.eye(n)[j]) - centres(-h * np.eye(n)[j])) / (2 * h)
                           for j in range(n)])
    cov = np.linalg.inv(jac.T @ jac) * sigma_m ** 2
    return np.sqrt(np.diag(cov)[:3]) / D2R


PAPER_SITES = [(-20, 0, 30), (0, 20, 120), (20, -20, 240)]

RUST_TEST = Path(__file__).resolve().parent.parent / "suite" / "calib_boresight.rs"


def hard_coded(order):
    """The bound calib_boresight.rs hard-codes for `order` (BOUND_ZYX_1MM_DEG / BOUND_XYZ_...)."""
    text = RUST_TEST.read_text()
    m = re.search(rf"const BOUND_{order.upper()}_1MM_DEG: \[f64; 3\] = \[([^\]]*)\];", text)
    if m is None:
        sys.exit(f"{RUST_TEST}: no BOUND_{order.upper()}_1MM_DEG constant")
    return [float(v) for v in m.group(1).split(",")]


def check():
    """The hard-coded bounds are this oracle's, to their 5 printed decimals (half a unit of the
    last decimal, plus float slack); `not diff <= tol` so a NaN fails."""
    failures = []
    for order in ("zyx", "xyz"):
        ours = bound_deg(PAPER_SITES, order)
        for k, (a, b) in enumerate(zip(ours, hard_coded(order))):
            if not abs(a - b) <= 0.5e-5 + 1e-9:
                failures.append(f"{order} angle {k}: oracle {a:.6f}, calib_boresight.rs {b}")
        print(order, "oracle", np.round(ours, 5), "hard-coded", hard_coded(order))
    if failures:
        print("FAIL:\n  " + "\n  ".join(failures))
        return 1
    print("calib_boresight.rs bounds match the oracle")
    return 0


if __name__ == "__main__":
    if sys.argv[1:] == ["--check"]:
        sys.exit(check())
    for order in ("zyx", "xyz"):
        print(order, "roll/pitch/heading 1-sigma (deg) at 1 mm:",
              np.round(bound_deg(PAPER_SITES, order), 5))
