#!/usr/bin/env python3
"""A survey day run on Dask (pipelines/cluster/kinescan_dask.py, a LocalCluster of 2 worker
processes) gives the single-machine day's bytes; so does a run in which the worker running a
unit is killed mid-unit (the scheduler reschedules the unit on a restarted worker), and one
through the Slurm array script (pipelines/cluster/kinescan_day.slurm, each array index run
here as Slurm would, without sbatch).

    python3 tests/dask/check_day.py FIXTURE KINESCAN

FIXTURE is written by `KINESCAN_DAY_OUT=FIXTURE cargo test --test suite day::tiles_do_not`:
the simulated day's inputs, `straight.toml` (the day in 25 m tiles) and its single-machine
output `a/`. KINESCAN is the kinescan executable. Exit status 1 on any difference.
"""

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import cloudpickle
from dask.distributed import Client, LocalCluster

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "pipelines" / "cluster"))
import kinescan_dask  # noqa: E402

cloudpickle.register_pickle_by_value(kinescan_dask)


def day_file(fixture, name):
    """`straight.toml` with the output folder `name`."""
    text = (fixture / "straight.toml").read_text()
    assert 'out = "a"' in text, text
    path = fixture / f"{name}.toml"
    path.write_text(text.replace('out = "a"', f'out = "{name}"'))
    return path


def las_files(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.las"))}


def counts(folder):
    r = json.loads((folder / "day.report.json").read_text())
    return [(p["name"], p["counts"]) for p in r["passes"]], r["totals"]


def slow_first_unit(fixture, kinescan):
    """A kinescan wrapper whose first `--unit` call records its unit and sleeps 5 s first."""
    mark = fixture / "first_unit"
    wrapper = fixture / "slow_first_unit.sh"
    wrapper.write_text(
        "#!/bin/sh\n"
        f'if [ "$3" = "--unit" ] && mkdir "{mark}" 2>/dev/null; then\n'
        f'  echo "$4" > "{mark}/unit.tmp" && mv "{mark}/unit.tmp" "{mark}/unit"; sleep 5\n'
        "fi\n"
        f'exec "{Path(kinescan).resolve()}" "$@"\n'
    )
    wrapper.chmod(0o755)
    return wrapper, mark / "unit"


def kill_worker_of(client, unit_file, killed):
    """Waits for the slow unit to start, then SIGKILLs the worker process running it."""
    deadline = time.time() + 120
    while not unit_file.exists() and time.time() < deadline:
        time.sleep(0.05)
    key = f"unit-{unit_file.read_text().strip()}"
    pids = client.run(os.getpid)
    for addr, keys in client.processing().items():
        if key in keys:
            os.kill(pids[addr], signal.SIGKILL)
            killed.append((key, addr))
            return


def slurm_day(fixture, kinescan):
    """The Slurm example's steps: plan, every array index, merge (kinescan found on PATH)."""
    day = str(day_file(fixture, "slurm"))
    bin_dir = fixture / "bin"
    bin_dir.mkdir(exist_ok=True)
    link = bin_dir / "kinescan"
    if not link.exists():
        link.symlink_to(Path(kinescan).resolve())
    env = dict(os.environ, PATH=f"{bin_dir}:{os.environ['PATH']}", SLURM_CPUS_PER_TASK="2")
    units = kinescan_dask.plan_units(str(link), day)
    script = Path(__file__).resolve().parents[2] / "pipelines" / "cluster" / "kinescan_day.slurm"
    for i in range(len(units)):
        env["SLURM_ARRAY_TASK_ID"] = str(i)
        subprocess.run(["bash", str(script), day], env=env, check=True)
    subprocess.run([str(link), "day", day, "--merge", "-q"], check=True)


def main():
    fixture, kinescan = Path(sys.argv[1]).resolve(), sys.argv[2]
    single = las_files(fixture / "a")
    problems = []
    if len(single) < 2:
        problems.append(f"the single-machine day has {len(single)} tiles")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster:
        with Client(cluster) as client:
            started = time.time()
            units = kinescan_dask.run_day(client, kinescan, day_file(fixture, "dask"))
            plain_s = time.time() - started
            wrapper, unit_file = slow_first_unit(fixture, kinescan)
            killed = []
            killer = threading.Thread(target=kill_worker_of, args=(client, unit_file, killed))
            killer.start()
            kinescan_dask.run_day(client, str(wrapper), day_file(fixture, "killed"))
            killer.join()
    slurm_day(fixture, kinescan)
    for name in ["dask", "killed", "slurm"]:
        if las_files(fixture / name) != single:
            problems.append(f"{name}: tiles differ from the single-machine day's")
        if counts(fixture / name) != counts(fixture / "a"):
            problems.append(f"{name}: report counts differ from the single-machine day's")
    if not killed:
        problems.append("no worker was killed while running a unit")
    for p in problems:
        print(f"dask day: {p}")
    if problems:
        sys.exit(1)
    print(f"dask day: {len(units)} units on 2 workers in {plain_s:.1f} s, {len(single)} tiles "
          f"identical to the single-machine day; worker running {killed[0][0]} killed, the "
          "unit rescheduled, tiles and counts identical; the Slurm array script too")


if __name__ == "__main__":
    main()
