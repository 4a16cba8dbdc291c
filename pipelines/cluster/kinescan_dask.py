#!/usr/bin/env python3
"""Runs a kinescan survey day on a Dask cluster: the plan, one task per work unit, the merge.

    python3 kinescan_dask.py DAY.toml [--scheduler tcp://host:8786] [--workers 2]
                            [--kinescan PATH] [--retries 3]

1. `kinescan day DAY.toml --plan` writes <out>/plan.json (on this machine).
2. Every unit of the plan is a Dask task running `kinescan day DAY.toml --unit ID` on a
   worker. A unit writes <out>/units/<ID>.las atomically and journals it, so a task that runs
   twice (a retry, a worker lost mid-task) gives the same bytes. A failed task is retried
   (`--retries`); a task whose worker dies is rescheduled by the scheduler. The unit's process
   dies with its worker (Linux: PR_SET_PDEATHSIG), so a lost worker leaves no writer behind.
3. When every unit is done, `kinescan day DAY.toml --merge` writes the day's files.

Without --scheduler a LocalCluster of --workers processes (one thread each) runs here. Workers
must see the day's files at the same paths (a shared filesystem) and have `kinescan` on their
PATH (or give --kinescan). docs/nightly.md, "On a cluster".
"""

import argparse
import ctypes
import json
import signal
import subprocess
import sys
import tomllib
from pathlib import Path

PR_SET_PDEATHSIG = 1


def _die_with_parent():
    """In the unit's process: be killed when the worker that started it dies (Linux)."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except OSError:
        pass


def run_unit(kinescan, day, unit):
    """A Dask task: one work unit. Raises on failure (Dask then retries it)."""
    done = subprocess.run(
        [kinescan, "day", day, "--unit", unit, "-q"],
        capture_output=True,
        text=True,
        preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None,
    )
    if done.returncode != 0:
        raise RuntimeError(f"unit {unit}: kinescan exited {done.returncode}: {done.stderr.strip()}")
    return unit


def out_folder(day):
    """The day's output folder: `[day] out`, relative to the day file's folder."""
    with open(day, "rb") as f:
        out = tomllib.load(f)["day"]["out"]
    return (Path(day).resolve().parent / out).resolve()


def plan_units(kinescan, day):
    """Writes the plan; gives its unit ids in plan order."""
    subprocess.run([kinescan, "day", day, "--plan"], check=True, stdout=subprocess.DEVNULL)
    plan = json.loads((out_folder(day) / "plan.json").read_text())
    return [u["id"] for u in plan["units"]]


def run_day(client, kinescan, day, retries=3):
    """Plans, runs every unit on `client`'s cluster, merges. Gives the unit ids."""
    day = str(Path(day).resolve())
    units = plan_units(kinescan, day)
    futures = [
        client.submit(run_unit, kinescan, day, u, key=f"unit-{u}", retries=retries, pure=False)
        for u in units
    ]
    client.gather(futures)
    subprocess.run([kinescan, "day", day, "--merge", "-q"], check=True)
    return units


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("day", help="the day file (DAY.toml)")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler")
    ap.add_argument("--workers", type=int, default=2, help="local worker processes (default 2)")
    ap.add_argument("--kinescan", default="kinescan", help="the kinescan executable")
    ap.add_argument("--retries", type=int, default=3, help="retries of a failed unit")
    a = ap.parse_args()
    from dask.distributed import Client, LocalCluster

    if a.scheduler:
        client = Client(a.scheduler)
    else:
        client = Client(LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True))
    with client:
        units = run_day(client, a.kinescan, a.day, a.retries)
    print(f"{a.day}: {len(units)} units on Dask, merged")


if __name__ == "__main__":
    main()
