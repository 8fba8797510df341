"""Throughput of ``mjjoint diagnose`` on a fleet: serial loop vs local process pool vs Dask.

K short recordings (an elastic gear with a 3 ms input delay, each its own multisine seed) are
diagnosed with a small budget (one round, two candidates) by each engine, into fresh folders:
  serial      --workers 1: one after another in this process (mjjoint already imported)
  pool        --workers W: W spawned processes (their start, importing mjjoint, is counted)
  dask        --scheduler: a distributed.LocalCluster of W single-thread worker processes,
              started and warmed up before the clock starts (a cluster outlives one command)
Printed: wall time, recordings per minute and the ratio to serial, and that every engine
wrote the same diagnosis.json bytes. The load average is printed too: on a shared machine
the ratios move with what else runs.

    python scripts/bench_fleet.py --recordings 6 --workers 2
"""
from __future__ import annotations

import argparse
import contextlib
import io
import os
import tempfile
import time
from pathlib import Path

from mjjoint.assets import ArmSpec
from mjjoint.cli import main
from mjjoint.excitation import Multisine
from mjjoint.identify.structure import Structure
from mjjoint.modelfile import dump_model_file
from mjjoint.sim import Simulator

GEAR = ("linear_stiffness", "transmission_damping")
VALUES = {"linear_stiffness.k1": 1e4, "transmission_damping.d": 2.0}
BUDGET = ["--window-length", "0.1", "--max-rounds", "1", "--candidates", "backlash,input_delay",
          "--fit-iter", "6", "--screen-iter", "4"]


def make_fleet(folder: Path, k: int, seconds: float) -> Path:
    """K recordings of the delayed gear and the model file without the delay; returns the model."""
    nominal = ArmSpec(segments=0, gravity=0.0)
    arm, joint = Structure.create(GEAR + ("input_delay",), nominal, 160.0, {**VALUES, "input_delay.delay": 3e-3}
                                  ).model_params()
    sim = Simulator(arm=arm, joint=joint)
    (folder / "recs").mkdir()
    for i in range(k):
        sim.run(Multisine(amplitude=0.05, f_min=1.0, f_max=30.0, seed=i).sample(1000.0, seconds)
                ).to_csv(folder / "recs" / f"robot{i}.csv")
    return dump_model_file(folder / "gear.toml", *Structure.create(GEAR, nominal, 160.0, VALUES).model_params())


def timed(folder: Path, model: Path, name: str, *engine: str) -> float:
    argv = ["diagnose", str(folder / "recs"), "--model", str(model), *BUDGET, "--out", str(folder / name), *engine]
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main(argv)
    seconds = time.perf_counter() - start
    if code != 0:
        raise SystemExit(f"{name}: exit code {code} (see {folder / name / 'fleet.csv'})")
    return seconds


def main_bench() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recordings", type=int, default=6)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=3.0, help="length of each recording")
    a = ap.parse_args()
    from distributed import LocalCluster

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        model = make_fleet(folder, a.recordings, a.seconds)
        times = {"serial": timed(folder, model, "serial", "--workers", "1"),
                 "pool": timed(folder, model, "pool", "--workers", str(a.workers))}
        with LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            # warm-up: the workers import mjjoint and load numba's cache before the clock starts
            timed(folder, model, "dask-warmup", "--scheduler", cluster.scheduler_address)
            times["dask"] = timed(folder, model, "dask", "--scheduler", cluster.scheduler_address)
        reference = {p.name: p.read_bytes() for p in sorted((folder / "serial").glob("*/diagnosis.json"))}
        same = all({p.name: p.read_bytes() for p in sorted((folder / n).glob("*/diagnosis.json"))} == reference
                   for n in times)
    print(f"{a.recordings} recordings of {a.seconds:g} s, {a.workers} workers, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f}")
    print(f"{'engine':8s} {'wall [s]':>9s} {'rec/min':>8s} {'vs serial':>9s}")
    for name, seconds in times.items():
        print(f"{name:8s} {seconds:9.1f} {60 * a.recordings / seconds:8.2f} {times['serial'] / seconds:8.2f}x")
    print(f"identical diagnosis.json bytes across engines: {same}")


if __name__ == "__main__":
    main_bench()
