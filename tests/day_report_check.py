#!/usr/bin/env python3
"""The morning report of a day (report.html) in a real browser: headless Chromium renders it
to a screenshot.

    python3 tests/day_report_check.py DAY_OUT SCREENSHOT.png

Checks: the HTML holds the key numbers of day.report.json (every pass's name and points
written, the day's totals, every pass's sigma_z median in mm as printed, the CRS; the tiles'
sigma rows when at most 8 tiles, else their summary row "N tiles"); the screenshot is not blank
(dark text on most of the page's rows) and shows the embedded plot (coloured markers: pixels
that are neither grey nor white). What this proves: the page is self-contained and renders with
its tables and its plot in Chromium; it does not read the numbers back from the pixels.
Exit status 1 on any failure.
"""

import json
import shutil
import subprocess
import sys
from pathlib import Path

from PIL import Image


def main():
    out, shot = Path(sys.argv[1]).resolve(), Path(sys.argv[2]).resolve()
    report = json.loads((out / "day.report.json").read_text())
    html = (out / "report.html").read_text()
    problems = []
    wanted = [str(report["totals"]["written"]), str(report["totals"]["read"])]
    for p in report["passes"]:
        wanted += [p["name"], str(p["counts"]["written"])]
    passes = [s for s in report["sigma"] if s["scope"].startswith("pass ")]
    tiles = [s for s in report["sigma"] if not s["scope"].startswith("pass ")]
    listed = passes + tiles if len(tiles) <= 8 else passes
    wanted += [f"{s['sigma_z_median_m'] * 1e3:.1f}" for s in listed]
    wanted.append(report["crs"])
    if len(tiles) > 8:
        wanted.append(f"{len(tiles)} tiles (range over tiles)")
    problems += [f"report.html lacks {w}" for w in wanted if f">{w}<" not in html]
    if "data:image/png;base64," not in html or "src=\"http" in html:
        problems.append("the plot is not embedded (or the page loads something)")
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        problems.append("no chromium")
    else:
        subprocess.run(
            [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
             "--window-size=1200,2400", f"--screenshot={shot}", (out / "report.html").as_uri()],
            check=True, capture_output=True,
        )
        img = Image.open(shot).convert("RGB")
        px = img.load()
        w, h = img.size
        dark_rows = sum(any(sum(px[x, y]) < 200 for x in range(0, w, 2)) for y in range(h))
        coloured = sum(
            1 for y in range(0, h, 2) for x in range(0, w, 2)
            if max(px[x, y]) - min(px[x, y]) > 80
        )
        if dark_rows < 200:
            problems.append(f"screenshot nearly blank: {dark_rows} rows with dark text")
        if coloured < 20:
            problems.append(f"screenshot shows no plot markers ({coloured} coloured pixels)")
    for p in problems:
        print(f"{out}/report.html: {p}")
    if problems:
        sys.exit(1)
    print(f"{out}/report.html: {len(wanted)} key numbers present; Chromium screenshot "
          f"{shot.name}: {dark_rows} rows of text, {coloured} plot pixels")


if __name__ == "__main__":
    main()
