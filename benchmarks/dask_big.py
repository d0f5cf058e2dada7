"""A squad Track of 10⁴ keys at 10⁹ query times, Zarr store in, Zarr store out, through zarr's writer.

Not an asv suite (it writes ~16 GB and takes many minutes); run it by hand::

    python -m benchmarks.dask_big --dir /path/with/30GB [--queries 1e9] [--repeat 2]
    python -m benchmarks.dask_big --dir /tmp/x --queries 1e8 --s3    # to a local S3-protocol server

Steps, all in one process so the rates are measured side by side:

1. write the input store ``in.zarr``: key times 0 .. Q-1 (so ``--fps 1``
   gives exactly Q query times) and 10⁴ float32 keys (a seeded random walk);
   with ``--s3``, on a moto S3 server started here on 127.0.0.1 (its objects
   in this process's memory and temporary files);
2. the in-memory reference: one `Track` (squad, float32) evaluated at 10⁷
   times in memory (best of 3), in queries per second, before and after the
   big run (the machine is shared: the ratio uses their mean);
3. ``/usr/bin/time -v python -m quatarray resample in.zarr -o out.zarr
   --fps 1 --method squad --quiet --force`` with Dask's threaded scheduler:
   wall time, peak RSS of that process (the targets: under 2 GB, and at
   least 70% of the in-memory rate); with ``--repeat N``, N runs alternating
   with in-memory measurements, each run's ratio taken against the
   in-memory rates just before and after it;
4. with ``--breakdown``, the parts of one chunk's cost, on 2 threads like the
   run: computing the chunks alone (queries and squad, stored nowhere), and
   writing ready chunks alone through zarr (the quaternions raw, the times
   LZ4-compressed, as the run writes them);
5. a check of a few output chunks against the in-memory Track.

Prints a JSON summary (with the machine: CPU, NumPy SIMD level, threads, date).
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


def write_input(path, queries, storage_options=None):
    import zarr
    rng = np.random.default_rng(20261123)
    half = np.cumsum(rng.normal(0, 0.05, (KEYS, 3)), axis=0) / 2   # smooth random walk of rotation vectors
    a = np.linalg.norm(half, axis=-1, keepdims=True)
    keys = np.concatenate([np.cos(a), np.sinc(a / np.pi) * half], axis=-1).astype(np.float32)
    times = np.linspace(0.0, float(queries - 1), KEYS)
    times[-1] = queries - 1
    g = zarr.open_group(path, mode="w", storage_options=storage_options)
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


class _Nowhere:
    """A `dask.array.store` target that keeps nothing: the chunks are computed, not written."""

    def __setitem__(self, key, value):
        pass


def breakdown(track, times, queries, threads=2):
    """Seconds per 2**21-query chunk: computing alone, and writing ready chunks alone through zarr."""
    import tempfile

    import dask
    import dask.array as da
    import zarr
    from zarr.codecs import BloscCodec

    from quatarray.formats import zarr as _zarr
    from quatarray import dask as qd
    rows = _zarr.CHUNK_QUATS
    n = min(queries, 24 * rows)
    chunks = -(-n // rows)
    t = da.minimum(times[0] + da.arange(n, chunks=rows, dtype=np.float64), times[-1])
    q = qd.evaluate(track, t)
    start = time.perf_counter()
    da.store([t, q], [_Nowhere(), _Nowhere()], lock=False, scheduler="threads", num_workers=threads)
    compute = (time.perf_counter() - start) / chunks
    ready_t, ready_q = t[:rows].compute(), q[:rows].compute()
    with tempfile.TemporaryDirectory(dir=os.environ.get("QA_BENCH_DIR")) as folder:
        g = zarr.open_group(os.path.join(folder, "w.zarr"), mode="w")
        zt = g.create_array("times", shape=(n,), chunks=(rows,), dtype=np.float64,
                            compressors=BloscCodec(cname="lz4", clevel=1, shuffle="shuffle"))
        zq = g.create_array("keys", shape=(n, 4), chunks=(rows, 4), dtype=np.float32, compressors=None)

        def write(i):
            sl = slice(i * rows, min(n, (i + 1) * rows))
            zt[sl] = ready_t[:sl.stop - sl.start]
            zq[sl] = ready_q[:sl.stop - sl.start]

        start, cpu = time.perf_counter(), os.times()
        with dask.config.set(scheduler="threads", num_workers=threads):
            dask.compute(*[dask.delayed(write)(i) for i in range(chunks)])
        write_s = (time.perf_counter() - start) / chunks
        write_cpu = [(b - a) / chunks for a, b in zip(cpu[:2], os.times()[:2])]   # user, system
        g2 = zarr.open_group(os.path.join(folder, "t.zarr"), mode="w")
        zt2 = g2.create_array("times", shape=(rows,), chunks=(rows,), dtype=np.float64,
                              compressors=BloscCodec(cname="lz4", clevel=1, shuffle="shuffle"))
        start = time.perf_counter()
        for _ in range(5):
            zt2[:] = ready_t
        times_s = (time.perf_counter() - start) / 5
    return {"chunks_measured": chunks, "threads": threads,
            "compute_s_per_chunk": round(compute, 4), "write_s_per_chunk_zarr": round(write_s, 4),
            "write_cpu_s_per_chunk_user_system": [round(c, 4) for c in write_cpu],
            "of_which_times_lz4_s_per_chunk_one_thread": round(times_s, 4)}


def _moto():
    """A moto S3 server on a free port of 127.0.0.1, a bucket on it, and the storage options."""
    import logging

    import s3fs
    from moto.server import ThreadedMotoServer
    logging.getLogger("werkzeug").setLevel(logging.ERROR)
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    options = {"key": "bench", "secret": "bench", "endpoint_url": "http://127.0.0.1:%d" % server.get_host_and_port()[1],
               "client_kwargs": {"region_name": "eu-west-1"}}
    s3fs.S3FileSystem(**options).mkdir("quatarray-bench")
    return server, options


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", required=True, help="folder for in.zarr and out.zarr")
    parser.add_argument("--queries", type=float, default=1e9)
    parser.add_argument("--keep", action="store_true", help="keep out.zarr")
    parser.add_argument("--repeat", type=int, default=1,
                        help="resample runs, alternating with in-memory measurements (median ratio reported)")
    parser.add_argument("--s3", action="store_true", help="stores on a moto S3 server on 127.0.0.1 (needs "
                                                         "moto[server] and s3fs)")
    parser.add_argument("--breakdown", action="store_true", help="also time computing and writing apart")
    args = parser.parse_args(argv)
    queries = int(args.queries)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sys.path.insert(0, root)
    from benchmarks.compare import machine
    from quatarray.interpolate import Track

    os.makedirs(args.dir, exist_ok=True)
    options, flags = None, []
    if args.s3:
        server, options = _moto()
        src, dst = "s3://quatarray-bench/in.zarr", "s3://quatarray-bench/out.zarr"
        flags = [a for k, v in options.items() for a in ("--storage-option", f"{k}={json.dumps(v) if isinstance(v, dict) else v}")]
    else:
        src, dst = os.path.join(args.dir, "in.zarr"), os.path.join(args.dir, "out.zarr")
    times, keys = write_input(src, queries, options)
    track = Track(times, keys, method="squad")
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "quatarray", "resample", src, "-o", dst,
           "--fps", "1", "--method", "squad", "--quiet", "--force", *flags]
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
    out = zarr.open_group(dst, mode="r", storage_options=options)
    n_out = out["keys"].shape[0]
    rng = np.random.default_rng(0)
    ok = True
    for i in rng.integers(0, n_out, 3):
        sl = slice(int(i), min(int(i) + 1000, n_out))
        ok &= bool(np.array_equal(out["keys"][sl], np.asarray(track(out["times"][sl]))))
    if args.s3:
        import s3fs
        nbytes = s3fs.S3FileSystem(**options).du(dst[5:])
    else:
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
        "store": "moto S3 server on 127.0.0.1 (in this process)" if args.s3 else "local disk",
        "machine": machine(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "cli_stdout": run.stdout.strip(),
    }
    if args.breakdown:
        result["breakdown"] = breakdown(track, times, queries)
    print(json.dumps(result, indent=1))
    if args.s3:
        server.stop()
    elif not args.keep:
        shutil.rmtree(dst, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
