#!/usr/bin/env python3
"""Checks a `kinescan diagnose` output folder: diagnosis.json has exactly the schema fields of
docs/conventions.md §8 (then the documented extras), summary.md and the listed plots exist, and
the corrected pipeline (verdict "effect") is a file `kinescan run` accepts (checked by
`kinescan validate`). `--expect-verdict WORD`: the verdict must be WORD (CI: the demo injects
no catalogue effect, only navigation errors, so its diagnosis must say `none`; a no-effect
survey gets `none` in 99 of 100 seeds, docs/diagnosis.md, and the demo's seed is fixed)."""
import json
import pathlib
import subprocess
import sys

SCHEMA = ["verdict", "effects", "estimate", "sigma", "located_in", "gap", "set"]
GAP = {"chi2_per_dof", "rms_m", "mean_m", "coverage_95", "n"}

args = sys.argv[1:]
expect = None
if "--expect-verdict" in args:
    k = args.index("--expect-verdict")
    expect = args[k + 1]
    del args[k : k + 2]
out = pathlib.Path(args[0])
d = json.loads((out / "diagnosis.json").read_text())
if expect is not None:
    assert d["verdict"] == expect, f"verdict {d['verdict']} {d['effects']}, expected {expect}"
assert list(d)[: len(SCHEMA)] == SCHEMA, f"schema fields first, in order: {list(d)}"
assert d["verdict"] in ("effect", "none", "unexplained"), d["verdict"]
for when in ("before", "after"):
    assert set(d["gap"][when]) == GAP, d["gap"][when]
assert set(d["estimate"]) == set(d["effects"]) == set(d["sigma"]), d
if d["verdict"] != "effect":
    assert d["effects"] == [] and d["set"] == [], d
# docs/conventions.md §8: "detectable" for EVERY catalogue name, "nuisance" with its source.
CATALOGUE = {
    "attitude_latency_s", "position_latency_s", "clock_offset_s", "clock_drift_ppm",
    "boresight_x_deg", "boresight_y_deg", "boresight_z_deg", "lever_arm_x_m", "lever_arm_y_m",
    "lever_arm_z_m", "range_zero_m", "range_scale_ppm", "encoder_offset_deg", "cone_deg",
    "heading_offset_deg",
}
assert set(d["detectable"]) == CATALOGUE, sorted(d["detectable"])
for name, v in d["detectable"].items():
    assert v is None or (isinstance(v, float) and v > 0), (name, v)
for k in ("position_tau_s", "attitude_tau_s", "position_scale", "attitude_scale"):
    p = d["nuisance"][k]
    assert p["source"] in ("estimated", "configured") and p["value"] > 0, (k, p)
# The knots the likelihood ran on: 0.02-0.1 s apart (docs/diagnosis.md, "The knot spacing").
assert 0.02 <= d["nuisance"]["knot_spacing_s"] <= 0.1, d["nuisance"]["knot_spacing_s"]
# The second, slow process: null (not searched) or searched, with its test and four values.
slow = d["nuisance"]["slow"]
if slow is not None:
    assert isinstance(slow["used"], bool) and slow["lr_threshold"] > 0, slow
    assert slow["used"] or slow["lr_statistic"] <= slow["lr_threshold"], slow
    for k in ("position_share", "attitude_share", "position_tau_s", "attitude_tau_s"):
        assert slow[k]["source"] in ("estimated", "configured") and slow[k]["value"] >= 0, (k, slow)
assert (out / "summary.md").read_text().startswith("# Diagnosis of ")
for png in d["plots"]:
    assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
if d["verdict"] == "effect":
    subprocess.run(
        ["cargo", "run", "--release", "--locked", "-q", "--", "validate", str(out / "corrected.toml")],
        check=True,
    )
print(f"diagnosis.json: verdict {d['verdict']} {d['effects']}, gap chi2/dof "
      f"{d['gap']['before']['chi2_per_dof']:.2f} -> {d['gap']['after']['chi2_per_dof']:.2f}")
