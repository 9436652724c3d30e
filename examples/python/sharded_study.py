"""The tracking study split into shards that run anywhere, then merged — bit for bit the study
of one `nmci.track` call.

Runs are seeded per run, so any engine that can call a Python function and return its
(picklable) result can run shards: a `concurrent.futures` process pool, Dask's `distributed`
(here a LocalCluster; point `Client` at a scheduler address for a real cluster) or Ray
(`ray.remote(nmci.track)`). This example uses Dask when it is installed and a process pool
otherwise.

    python examples/python/sharded_study.py [--quick]
"""

import sys
import time

import numpy as np

import nmci


def run_shard(first_run, count, steps):
    return nmci.track(runs=count, steps=steps, first_run=first_run)


def main():
    quick = "--quick" in sys.argv
    runs, steps, per_shard = (4, 30, 1) if quick else (15, 400, 3)
    starts = list(range(0, runs, per_shard))
    sizes = [min(per_shard, runs - s) for s in starts]
    t = time.perf_counter()
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=2) as pool:
            shards = list(pool.map(run_shard, starts, sizes, [steps] * len(starts)))
        engine = "a concurrent.futures process pool (2 workers)"
    else:
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, Client(cluster) as client:
            shards = client.gather(client.map(run_shard, starts, sizes, [steps] * len(starts)))
        engine = "a dask.distributed LocalCluster (2 worker processes)"
    sharded = time.perf_counter() - t

    study = nmci.merge(shards)
    spans = [(s.first_run, s.first_run + s.runs) for s in shards]
    print(f"{len(shards)} shards of runs {spans} on {engine}: {sharded:.1f} s")
    one = nmci.track(runs=runs, steps=steps)
    same = study.summary == one.summary and all(
        np.array_equal(getattr(study, k), getattr(one, k)) for k in ("nees", "rmse", "two_sigma", "coin")
    )
    print(f"merged study equals one nmci.track of {runs} runs bit for bit: {same}")
    for name in ("ci", "nmci"):
        s = study.summary[name]
        print(f"  {name:<5} RMSE {s['rmse_mean']:.3f}  2σ {s['two_sigma_mean']:.3f}  NEES {s['nees_mean']:.2f}  COIN max {s['coin_max']:.3f}")
    if not same:
        sys.exit("the merged study differs from the single run")


if __name__ == "__main__":  # worker processes import this file: run only in the main one
    main()
