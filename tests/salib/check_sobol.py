#!/usr/bin/env python3
"""SALib oracle for kinescan's Sobol indices (acceptance).

Runs the model export (examples/salib_model.rs), then:
1. same samples: SALib's sobol.analyze on our exported Saltelli design and outputs must give
   our first-order and total indices (same estimators: Saltelli 2010, Jansen) to 1e-9;
2. independent samples: SALib draws its own Saltelli sample (scrambled Sobol sequence, normal
   inputs), our model evaluates it, SALib analyses it; the indices must agree with ours (from
   our own pseudo-random design of 2^15 base rows) within 0.02 absolute per input and output.

Usage: python3 tests/salib/check_sobol.py [--model PATH_TO_salib_model]
(default: builds it with `cargo build --release --example salib_model`). Needs numpy, SALib.
"""

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from SALib.analyze import sobol as sobol_analyze
from SALib.sample import sobol as sobol_sample

CRATE = Path(__file__).resolve().parents[2]
OUTPUTS = ["east", "north", "up"]
TOL_SAME = 1e-9
TOL_INDEPENDENT = 0.02
SALIB_BASE_ROWS = 2**14


def model_binary(given):
    if given:
        return Path(given)
    subprocess.run(
        ["cargo", "build", "--release", "--example", "salib_model"], cwd=CRATE, check=True
    )
    return CRATE / "target" / "release" / "examples" / "salib_model"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--model")
    args = ap.parse_args()
    exe = model_binary(args.model)
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        subprocess.run([str(exe), "export", str(tmp)], check=True)
        problem_in = json.loads((tmp / "problem.json").read_text())
        ours = json.loads((tmp / "ours.json").read_text())
        names = problem_in["names"]
        d = len(names)
        problem = {
            "num_vars": d,
            "names": names,
            "bounds": [[0.0, s] for s in problem_in["sigmas"]],
            "dists": ["norm"] * d,
        }

        # 1. Same samples, same estimators.
        y_shared = np.fromfile(tmp / "design_y.f64", dtype="<f8").reshape(-1, 3)
        worst_same = 0.0
        for k, out in enumerate(OUTPUTS):
            s = sobol_analyze.analyze(problem, y_shared[:, k], calc_second_order=False, num_resamples=2, seed=1)
            for i in range(d):
                for key, ours_key in (("S1", "first"), ("ST", "total")):
                    diff = abs(s[key][i] - ours["same_sample"][k][i][ours_key])
                    # NaN-proof: max() keeps the first of (worst, nan) and `nan > tol` is
                    # False, so the test is `not diff <= tol` and a NaN is reported.
                    worst_same = diff if not diff <= worst_same else worst_same
                    if not diff <= TOL_SAME:
                        failures.append(f"same-sample {out} {names[i]} {key}: diff {diff:.3e}")

        # 2. Independent samples.
        x = sobol_sample.sample(problem, SALIB_BASE_ROWS, calc_second_order=False, seed=7)
        x.astype("<f8").tofile(tmp / "salib_x.f64")
        subprocess.run([str(exe), "eval", str(tmp / "salib_x.f64"), str(tmp / "salib_y.f64")], check=True)
        y = np.fromfile(tmp / "salib_y.f64", dtype="<f8").reshape(-1, 3)
        worst = 0.0
        print(f"{'output':6} {'input':12} {'S1 ours':>9} {'S1 SALib':>9} {'ST ours':>9} {'ST SALib':>9}")
        for k, out in enumerate(OUTPUTS):
            s = sobol_analyze.analyze(problem, y[:, k], calc_second_order=False, num_resamples=100, seed=1)
            for i in range(d):
                o = ours["independent"][k][i]
                print(f"{out:6} {names[i]:12} {o['first']:9.4f} {s['S1'][i]:9.4f} {o['total']:9.4f} {s['ST'][i]:9.4f}")
                for key, ours_key in (("S1", "first"), ("ST", "total")):
                    diff = abs(s[key][i] - o[ours_key])
                    worst = diff if not diff <= worst else worst
                    if not diff <= TOL_INDEPENDENT:
                        failures.append(f"independent {out} {names[i]} {key}: ours {o[ours_key]:.4f} SALib {s[key][i]:.4f}")
    print(f"same samples: worst |difference| {worst_same:.2e} (bound {TOL_SAME})")
    print(f"independent samples: worst |difference| {worst:.4f} (bound {TOL_INDEPENDENT})")
    if failures:
        print("FAIL:\n  " + "\n  ".join(failures))
        return 1
    print("OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
