"""A squad Track of 10⁴ keys at 10⁹ query times, Zarr store in, Zarr store out.

Not an asv suite (it writes ~24 GB and takes many minutes); run it by hand::

    python -m benchmarks.dask_big --dir /path/with/30GB [--queries 1000000000]

Steps, all in one process so the rates are measured side by side:

1. write the input store ``in.zarr``: key times 0 .. Q-1 (so ``--fps 1``
   gives exactly Q query times) and 10⁴ float32 keys (a seeded random walk);
2. the in-memory reference: one `Track` (squad, float32) evaluated at 10⁷
   times in memory (best of 3), in queries per second, before and after the
   big run (the machine is shared: the ratio uses their mean);
3. ``/usr/bin/time -v python -m quatarray resample in.zarr -o out.zarr
   --fps 1 --method squad --quiet`` with Dask's threaded scheduler: wall time,
   peak RSS (the targets: under 2 GB, and at least 70% of the in-memory rate);
   with ``--repeat N``, N runs alternating with in-memory measurements, each
   run's ratio taken against the in-memory rates just before and after it;
4. a check of a few output chunks against the in-memory Track.

Prints a JSON summary (with the machine: CPU, NumPy SIMD level, threads).
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time

import numpy as np

KEYS = 10_000
REFERENCE = 10_000_000


def write_input(path, queries):
    import zarr
    rng = np.random.default_rng(20261123)
    half = np.cumsum(rng.normal(0, 0.05, (KEYS, 3)), axis=0) / 2   # smooth random walk of rotation vectors
    a = np.linalg.norm(half, axis=-1, keepdims=True)
    keys = np.concatenate([np.cos(a), np.sinc(a / np.pi) * half], axis=-1).astype(np.float32)
    times = np.linspace(0.0, float(queries - 1), KEYS)
    times[-1] = queries - 1
    g = zarr.open_group(path, mode="w")
    g["times"] = times
    g["keys"] = keys
    return times, keys


def in_memory_rate(track, times, n):
    t = np.linspace(times[0], times[-1], n)
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        track(t)
        best = min(best, time.perf_counter() - start)
    return n / best


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", required=True, help="folder for in.zarr and out.zarr")
    parser.add_argument("--queries", type=float, default=1e9)
    parser.add_argument("--keep", action="store_true", help="keep out.zarr")
    parser.add_argument("--repeat", type=int, default=1,
                        help="resample runs, alternating with in-memory measurements (median ratio reported)")
    args = parser.parse_args(argv)
    queries = int(args.queries)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sys.path.insert(0, root)
    from benchmarks.compare import machine
    from quatarray.interpolate import Track

    os.makedirs(args.dir, exist_ok=True)
    src, dst = os.path.join(args.dir, "in.zarr"), os.path.join(args.dir, "out.zarr")
    times, keys = write_input(src, queries)
    track = Track(times, keys, method="squad")
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "quatarray", "resample", src, "-o", dst,
           "--fps", "1", "--method", "squad", "--quiet"]
    env = dict(os.environ, PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
    runs = []
    rate_memory = in_memory_rate(track, times, REFERENCE)
    for _ in range(args.repeat):   # the in-memory rate right before and after each run
        start = time.perf_counter()
        run = subprocess.run(cmd, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - start
        if run.returncode:
            sys.exit(f"resample failed ({run.returncode}):\n{run.stdout}\n{run.stderr}")
        rate_after = in_memory_rate(track, times, REFERENCE)
        rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", run.stderr).group(1))
        runs.append((wall, rss_kb, rate_memory, rate_after))
        rate_memory = rate_after

    import zarr
    out = zarr.open_group(dst, mode="r")
    n_out = out["keys"].shape[0]
    rng = np.random.default_rng(0)
    ok = True
    for i in rng.integers(0, n_out, 3):
        sl = slice(int(i), min(int(i) + 1000, n_out))
        ok &= bool(np.array_equal(out["keys"][sl], np.asarray(track(out["times"][sl]))))
    nbytes = sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(dst) for f in fs)
    ratios = [n_out / w / ((a + b) / 2) for w, _, a, b in runs]
    wall, rss_kb = runs[int(np.argsort(ratios)[len(ratios) // 2])][:2]
    result = {
        "queries": n_out, "keys": KEYS, "method": "squad", "dtype": "float32", "runs": len(runs),
        "wall_s": [round(w, 1) for w, *_ in runs], "peak_rss_MB": max(round(r / 1024) for _, r, *_ in runs),
        "rate_dask_Mq_s": [round(n_out / w / 1e6, 3) for w, *_ in runs],
        "rate_memory_1e7_Mq_s": [round(runs[0][2] / 1e6, 3)] + [round(r[3] / 1e6, 3) for r in runs],
        "ratio_each": [round(r, 3) for r in ratios], "ratio_median": round(float(np.median(ratios)), 3),
        "load_average": os.getloadavg(),
        "output_GB_on_disk": round(nbytes / 1e9, 2), "output_GB_raw": round(n_out * 4 * 4 / 1e9, 2),
        "spot_check_equal": ok, "command": " ".join(cmd[2:]).replace(sys.executable, "python"),
        "machine": machine(), "cli_stdout": run.stdout.strip(),
    }
    print(json.dumps(result, indent=1))
    if not args.keep:
        shutil.rmtree(dst, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
