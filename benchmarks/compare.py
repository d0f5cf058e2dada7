"""Side-by-side timings of quatarray and its peers, in one process, and the speed targets.

Usage::

    python -m benchmarks.compare            # full table (several minutes)
    python -m benchmarks.compare --quick    # the rows the targets need (about 70 s on 2 cores)
    python -m benchmarks.compare --targets  # only the targets, PASS / FAIL
    python -m benchmarks.compare --json results.json
    python -m benchmarks.compare --sweep    # every Rotation method etc. at every batch size

Each row runs one asv benchmark (same class, same seeded data) for every
installed library.  The libraries are timed **interleaved**: repeat r times
quatarray, quatarray on one thread, scipy, then each peer, and so on,
keeping the best time per call of each -- on a noisy, shared machine only
the ratios inside one run mean anything.  The reference column is a plain
``np.add`` of two arrays of the batch's quaternions (same dtype and byte
count): the memory-bandwidth bound of an element-wise operation.
``peer/qa`` > 1 means quatarray is faster; ``1T`` is quatarray on one
thread (``quatarray.num_threads(1)``, as ``QUATARRAY_NUM_THREADS=1``).

The header names the machine: CPU model, NumPy's SIMD level (X86_V4 =
AVX-512, X86_V3 = AVX2) and the threads quatarray uses.  To see how an
AVX2-only CPU fares on an AVX-512 one, turn NumPy's AVX-512 loops off:
``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" python -m
benchmarks.compare --quick`` (the compiled peers keep their own code).
"""

import argparse
import datetime
import gc
import json
import platform
import os
import subprocess
import sys
import time
import tracemalloc

import numpy as np

from . import _common
from ._common import LIBS, installed
from .conversions import SLOW_FROM_MATRIX

__all__ = ["main", "Row", "measure", "targets"]

PEERS = LIBS[1:]


class Row:
    """One operation at one size: an asv class, a benchmark method, its params (without lib).

    `size` is the number of quaternions whose np.add is the reference (None:
    no reference row); `libs` limits the libraries compared; `twin` (a dtype)
    also times quatarray on the same row's data in that dtype, interleaved with
    the others (the float32 targets' float64 time: two rows timed minutes apart
    on a shared machine compare two different loads).
    """

    def __init__(self, op, cls, method, params, size=None, libs=LIBS, n=None, one_thread=None, twin=None):
        self.op, self.cls, self.method, self.params = op, cls, method, tuple(params)
        self.size, self.libs, self._n, self.twin = size, libs, n, twin
        # one-thread timings where threads can matter (batches past the engine's threshold)
        self.one_thread = one_thread if one_thread is not None else (self.n or 0) >= 100_000

    @property
    def dtype(self):
        return next((p for p in self.params if p in _common.DTYPES), "float64")

    @property
    def n(self):
        if self._n is not None:
            return self._n
        return self.params[0] if isinstance(self.params[0], int) else None

    def key(self):
        return (self.op, self.n, self.dtype)


def _callable(row, lib, setups=None):
    """Set the benchmark up for `lib`; return (zero-argument call, seconds of the warm-up
    call), or None when skipped.

    `setups` (a dict) holds benchmark objects already set up, by class and
    parameters: rows of one class with the same parameters (the conversions,
    the rigid transforms) share one setup instead of building the same inputs again.
    """
    args = row.params + (lib,)
    key = (row.cls, args)
    bench = None if setups is None else setups.get(key)
    if hasattr(row.cls, "setup_cache"):
        args = (_cache(row.cls),) + args
    try:
        if bench is None:
            bench = row.cls()
            bench.setup(*args)
            if setups is not None:
                setups[key] = bench
        fn = getattr(bench, row.method)
        t0 = time.perf_counter()
        fn(*args)  # warm-up, and checks that the library has the operation
        warm = time.perf_counter() - t0
    except NotImplementedError:
        return None
    return (lambda: fn(*args)), warm


_CACHES = {}


def _cache(cls):
    if cls not in _CACHES:
        import os
        import tempfile
        tmp = tempfile.mkdtemp(prefix="quatarray-bench-")
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            _CACHES[cls] = cls().setup_cache()
        finally:
            os.chdir(cwd)
    return _CACHES[cls]


def _number(fn, min_time):
    """Calls per sample so that a sample lasts at least `min_time` seconds."""
    number = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        dt = time.perf_counter() - t0
        if dt >= min_time or number >= 1 << 20:
            return number
        number *= 2 if dt == 0 else max(2, min(10, int(1.5 * min_time / dt)))


def measure(calls, repeat, min_time, warm=None, budget=3.0):
    """Best seconds per call of each callable in `calls` (dict), timed interleaved.

    `warm` maps a key to the duration of a call already made: one that took
    at least `min_time` is timed one call per sample without calibration;
    a faster one gets an untimed call before each sample (so that memory
    freed by the previous library is not counted against it), and slow
    calls get only as many samples as fit in `budget` seconds (at least
    one; a call slower than `budget` counts its warm-up as its sample).
    """
    warm = warm or {}
    numbers, samples = {}, {}
    best = dict.fromkeys(calls, float("inf"))
    for k, f in calls.items():
        w = warm.get(k, 0.0)
        numbers[k] = 1 if w >= min_time else _number(f, min_time)
        samples[k] = repeat if w * repeat <= budget else max(int(budget / w), 0)
        if samples[k] == 0:
            best[k] = w
    for r in range(repeat):
        for k, f in calls.items():
            if r >= samples[k]:
                continue
            n = numbers[k]
            if n > 1:
                f()  # untimed: the first call after another library's pays its page faults
            gc.disable()
            t0 = time.perf_counter()
            for _ in range(n):
                f()
            dt = (time.perf_counter() - t0) / n
            gc.enable()
            best[k] = min(best[k], dt)
    return best


ONE = "quatarray 1T"


def _twin(dtype):
    """The key of a row's quatarray time in its `twin` dtype."""
    return f"quatarray {dtype}"


def _one_thread(call):
    import quatarray

    def run():
        with quatarray.num_threads(1):
            return call()
    return run


def _add_reference(size, dtype):
    a = np.random.default_rng(0).standard_normal((size, 4)).astype(dtype)
    b = a[::-1].copy()
    return lambda: np.add(a, b)


def run_rows(rows, repeat, min_time, log=None, budget=3.0):
    """Time every row; returns a list of result dicts."""
    results = []
    setups = {}   # the current row's set-up benchmarks, kept for the next row if it shares them
    for row in rows:
        calls, warm = {}, {}
        used = {(row.cls, row.params + (lib,)) for lib in row.libs}
        for key in [k for k in setups if k not in used]:
            del setups[key]
        for lib in row.libs:
            if installed(lib):
                got = _callable(row, lib, setups)
                if got is not None:
                    calls[lib], warm[lib] = got
        if "quatarray" not in calls:
            results.append(dict(op=row.op, n=row.n, dtype=row.dtype, times={}, skipped=True))
            continue
        if row.one_thread:
            calls[ONE], warm[ONE] = _one_thread(calls["quatarray"]), warm["quatarray"]
        if row.twin:
            twin = Row(row.op, row.cls, row.method, [row.twin if p == row.dtype else p for p in row.params])
            got = _callable(twin, "quatarray")
            if got is not None:
                calls[_twin(row.twin)], warm[_twin(row.twin)] = got
        if row.size:
            calls["np.add"] = _add_reference(row.size, row.dtype)
        best = measure(calls, repeat, min_time, warm, budget)
        res = dict(op=row.op, n=row.n, dtype=row.dtype, params=list(row.params), times=best)
        results.append(res)
        if log:
            log(_format_row(res))
        _release(calls)
    return results


def _release(calls):
    calls.clear()
    gc.collect()


# --------------------------------------------------------------------------- memory and import

def peak_memory(row, call):
    """(peak bytes allocated during one call above what existed before, plus the scratch
    quatarray's threads keep afterwards; output bytes).  The call is made once before,
    so that the scratch it keeps exists and is counted once."""
    bench = row.cls()
    bench.setup(*row.params, "quatarray")
    call(bench)
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        out = call(bench)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    return peak + scratch_kept(), np.asarray(out).nbytes


def import_times(repeat):
    """Best wall time of ``python -c "import quatarray"`` and ``... "import numpy"``, interleaved.

    quatarray's bytecode is compiled first, as ``pip install`` does: a checkout
    run with ``PYTHONDONTWRITEBYTECODE=1`` would otherwise compile every module
    on every import and time the compiler (about 0.1 s), not the import.
    """
    import compileall
    import importlib.util
    package = os.path.dirname(importlib.util.find_spec("quatarray").origin)
    compileall.compile_dir(package, quiet=1)
    best = {"quatarray": float("inf"), "numpy": float("inf")}
    for _ in range(repeat):
        for mod in best:
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", f"import {mod}"], check=True)
            best[mod] = min(best[mod], time.perf_counter() - t0)
    check = "import sys, quatarray; print(sorted(m for m in ('scipy', 'quaternion', 'quaternionic', 'numba') if m in sys.modules))"
    loaded = subprocess.run([sys.executable, "-c", check], check=True, capture_output=True, text=True).stdout
    return best, loaded.strip()


# --------------------------------------------------------------------------- rows

BIG = 1_000_000
#: Peer operations skipped at N = 10⁶ because they are known to be more than 100x
#: slower than quatarray there (numpy-quaternion's and quaternionic's from_matrix
#: take 23-26 s per call, quatarray about 0.07 s); their N = 10⁴ rows stand in.
SLOW_PEERS = {("from_matrix", lib) for lib in SLOW_FROM_MATRIX}

#: Operations the compiled peers have, compared at default threads and on one thread.
RIGID_OPS = {"rigid apply": "time_apply", "rigid compose": "time_compose", "rigid apply inverse": "time_apply_inverse",
             "rigid inv": "time_inv", "rigid from_matrix": "time_from_matrix", "rigid as_matrix": "time_as_matrix",
             "rigid compose, then as_matrix": "time_compose_as_matrix"}
PEER_OPS = ("product", "conjugate", "normalize", "exp", "log", "power", "rotate",
            "as_matrix", "from_matrix", "as_rotvec", "from_rotvec", "slerp")
MEMORY_BOUND = ("product", "conjugate", "inv", "normalize")
#: Operations with a float32 target (float64 time / float32 time), timed interleaved in one row.
FLOAT32_OPS = ("product", "slerp")
#: Rotation methods timed on one rotation (shape ()) against scipy's (benchmarks.sweep, size 'single')
SINGLE_METHODS = ("from_quat", "as_quat", "from_matrix", "as_matrix", "from_rotvec", "as_rotvec",
                  "from_mrp", "as_mrp", "from_euler", "as_euler", "from_davenport", "as_davenport",
                  "apply", "mul", "pow", "inv", "magnitude", "approx_equal", "mean", "reduce",
                  "identity", "random", "align_vectors")


def _rows(full):
    """The rows of the table; without `full`, only those the targets need, with the libraries they need."""
    from .algebra import Algebra
    from .conversions import Conversions
    from .pairwise import Pairwise
    from .resample import Resample
    from .rotate import RotateVectors
    from .sweep import SizeSweep
    from .tracks import OneQuery, Tracks

    qa, sp, nq, qn = "quatarray", "scipy", "numpy-quaternion", "quaternionic"
    rows = []

    def add(op, cls, method, sizes, dtypes, libs):
        for n in sizes:
            for dt in dtypes:
                use = [lib for lib in (LIBS if full else libs) if not (n >= BIG and (op, lib) in SLOW_PEERS)]
                if not full and dt != "float64":   # the float32 targets compare quatarray with itself
                    use, one = [qa], False
                else:
                    one = None
                twin = "float64" if dt == "float32" and op in FLOAT32_OPS else None
                rows.append(Row(op, cls, method, (n, dt), size=n, libs=use, one_thread=one, twin=twin))

    sizes = _common.SIZES if full else [BIG]
    f64 = ["float64"]
    dtypes = _common.DTYPES if full else f64
    add("product", Algebra, "time_product", _common.SIZES if full else [1, BIG], _common.DTYPES, (qa, sp, nq, qn))
    for op in ("conjugate", "inv", "normalize", "magnitude", "exp", "log", "power", "rotation_power"):
        add(op, Algebra, f"time_{op}", sizes, dtypes, (qa, nq, qn) if op in PEER_OPS else (qa, sp))
    add("rotate", RotateVectors, "time_rotate", sizes, dtypes, (qa, nq, qn))
    add("apply", RotateVectors, "time_apply", _common.SIZES if full else [1, BIG], dtypes, (qa, sp))
    for op in ("as_matrix", "from_matrix", "as_rotvec", "from_rotvec", "as_euler", "from_euler"):
        add(op, Conversions, f"time_{op}", sizes, dtypes, (qa, sp) + ((nq, qn) if op in PEER_OPS else ()))
    if not full:  # the peers' from_matrix at 10⁴ (10⁶ is skipped, see SLOW_PEERS)
        add("from_matrix", Conversions, "time_from_matrix", [10_000], f64, (qa, nq, qn))
    add("slerp", Pairwise, "time_slerp", sizes, _common.DTYPES, (qa, nq, qn))
    if full:
        add("nlerp", Pairwise, "time_nlerp", sizes, dtypes, LIBS)
    rows.append(Row("Slerp(t), one query", OneQuery, "time_slerp_call", ("float64",), libs=(qa, sp), n=1))
    for method in SINGLE_METHODS:   # N = 1: one rotation, where the per-call cost decides
        rows.append(Row(f"Rotation {method}", SizeSweep, "time_op", (method, "single"), libs=(qa, sp), n=1))
    tracks = [(10_000, BIG)] + ([(10, 10), (10, BIG), (10_000, 10)] if full else [])
    for k, m in tracks:
        for method, libs in (("slerp", (qa, sp)), ("squad", (qa, nq, qn))) + ((("bezier", (qa, sp)),) if full else ()):
            rows.append(Row(f"track {method}, {k} keys", Tracks, f"time_{method}", (k, m, "float64"),
                            size=m, libs=LIBS if full else libs, n=m))
    from .rigid import RigidTransforms, SplineEvaluate
    rows.append(Row("spline eval, 10000 keys", SplineEvaluate, "time_rotations", (10_000, BIG, "float64"),
                    libs=(qa, sp), n=BIG))
    rows.append(Row("spline build, 10000 keys", SplineEvaluate, "time_build", (10_000, 10, "float64"),
                    libs=(qa, sp), n=10_000, one_thread=False))
    for n in (1, BIG):   # n outer: the rows of one n share their setup
        for op in RIGID_OPS if n == 1 else ("rigid apply", "rigid compose"):
            rows.append(Row(op, RigidTransforms, RIGID_OPS[op], (n, "float64"), size=n, libs=(qa, sp)))
    if full:
        from .timeseries import ReduceKeys
        for method in ("slerp", "squad"):
            rows.append(Row(f"reduce_keys {method}, 10000 x 10", ReduceKeys, "time_reduce",
                            (10_000, 10, method, "float64"), libs=(qa,), n=100_000))
        for method in ("slerp", "squad"):   # the size: one call each (its warm-up is its sample)
            rows.append(Row(f"reduce_keys {method}, 1e6 x 50", ReduceKeys, "time_reduce",
                            (1_000_000, 50, method, "float64"), libs=(qa,), n=50_000_000, one_thread=False))
        for case in ("npz", "bvh"):
            rows.append(Row(f"resample {case}", Resample, "time_resample", (case,), libs=Resample.params[-1],
                            one_thread=True))
    return rows


# --------------------------------------------------------------------------- report

def _fmt(t):
    if t is None or not np.isfinite(t):
        return "-"
    for unit, scale in (("s", 1), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9)):
        if t >= scale:
            return f"{t / scale:.3g} {unit}"
    return f"{t / 1e-9:.3g} ns"


def _format_row(res):
    t = res["times"]
    qa = t.get("quatarray")
    cells = [f"{res['op']:<24}", f"{res['n'] if res['n'] is not None else '':>8}", f"{res['dtype']:<8}",
             f"{_fmt(qa):>10}", f"{_fmt(t.get(ONE)):>10}"]
    add = t.get("np.add")
    cells.append(f"{_fmt(add):>10} {('%.2fx' % (qa / add)) if add else '':>7}")
    for lib in PEERS:
        if lib in t:
            cells.append(f"{_fmt(t[lib]):>10} {t[lib] / qa:>7.2f}")
        else:
            cells.append(f"{'-':>10} {'':>7}")
    for key in [k for k in t if k.startswith("quatarray float")]:   # a twin dtype's time (`Row`)
        cells.append(f"  {key.split()[1]} {_fmt(t[key])} = {t[key] / qa:.2f}x")
    return " ".join(cells)


def header():
    cols = [f"{'operation':<24}", f"{'N':>8}", f"{'dtype':<8}", f"{'quatarray':>10}", f"{'1T':>10}",
            f"{'np.add':>10} {'qa/add':>7}"] + [f"{lib[:10]:>10} {'/qa':>7}" for lib in PEERS]
    line = " ".join(cols)
    return line + "\n" + "-" * len(line)


def _find(results, op, n=None, dtype="float64"):
    for r in results:
        if r["op"] == op and (n is None or r["n"] == n) and r["dtype"] == dtype and r["times"]:
            return r["times"]
    return None


def targets(results, memory, imports):
    """The speed targets: list of (description, measured value, PASS/FAIL/n/a).

    Ratios > 1 mean quatarray is faster, except ``quatarray / np.add`` (time
    over the memory bound, lower is better).
    """
    out = []

    def ratio(op, peer, n=BIG, dtype="float64", qa="quatarray"):
        t = _find(results, op, n, dtype)
        if not t or peer not in t or qa not in t:
            return None
        return t[peer] / t[qa]

    def check(desc, value, ok, unit="x"):
        if value is None:
            out.append((desc, "n/a", "n/a"))
        else:
            out.append((desc, f"{value:.2f}{unit}", "PASS" if ok(value) else "FAIL"))

    peers = ("numpy-quaternion", "quaternionic")
    for op in PEER_OPS + ("track squad, 10000 keys",):
        n = 10_000 if any((op, p) in SLOW_PEERS for p in peers) else BIG
        where = "" if n == BIG else " (N=1e4: the peers take >100x longer at 1e6)"
        for qa, label in (("quatarray", ""), (ONE, ", 1 thread")):
            got = [ratio(op, p, n, qa=qa) for p in peers]
            got = [g for g in got if g is not None]
            if qa == "quatarray" and op not in MEMORY_BOUND:
                check(f"{op}: faster peer / quatarray >= 1{where}", min(got) if got else None, lambda v: v >= 1)
            elif got:   # the memory-bound ones: their target is the np.add floor below (issue 23, §4)
                out.append((f"{op}: faster peer / quatarray{label}{where}", f"{min(got):.2f}x", "info"))
    for op in MEMORY_BOUND:
        t = _find(results, op, BIG)
        check(f"{op}: quatarray / np.add <= 2", t["quatarray"] / t["np.add"] if t and "np.add" in t else None,
              lambda v: v <= 2)
    for op, goal in (("as_euler", 3), ("from_rotvec", 3), ("as_matrix", 2), ("from_matrix", 2),
                     ("as_rotvec", 2), ("from_euler", 2), ("track slerp, 10000 keys", 30)):
        name = "Slerp track 1e4 keys -> 1e6 queries" if op.startswith("track") else op
        check(f"{name}: scipy / quatarray >= {goal}", ratio(op, "scipy"), lambda v, g=goal: v >= g)
    check("pairwise slerp: numpy-quaternion / quatarray >= 3", ratio("slerp", "numpy-quaternion"), lambda v: v >= 3)
    check("squad track 1e4 keys -> 1e6 queries: numpy-quaternion / quatarray >= 8",
          ratio("track squad, 10000 keys", "numpy-quaternion"), lambda v: v >= 8)
    for op in FLOAT32_OPS:
        t32, t64 = _find(results, op, BIG, "float32"), _find(results, op, BIG, "float64")
        if t32 and _twin("float64") in t32:   # timed interleaved in the float32 row
            v = t32[_twin("float64")] / t32["quatarray"]
        else:
            v = t64["quatarray"] / t32["quatarray"] if t32 and t64 else None
        check(f"float32 {op}: float64 / float32 time >= 1.5", v, lambda v: v >= 1.5)
    for op, (peak, size) in memory.items():
        check(f"memory {op} N=1e6: (peak extra + scratch kept) / output <= 1.5", peak / size if size else None,
              lambda v: v <= 1.5)
    # rotation splines and rigid transforms (scipy is the only peer that has them)
    check("RotationSpline 1e4 keys -> 1e6 times (order 0): scipy / quatarray >= 10",
          ratio("spline eval, 10000 keys", "scipy"), lambda v: v >= 10)
    check("RotationSpline build, 1e4 keys: scipy / quatarray >= 1",
          ratio("spline build, 10000 keys", "scipy", n=10_000), lambda v: v >= 1)
    for op in ("rigid apply", "rigid compose"):
        check(f"{op} N=1e6: scipy / quatarray >= 2", ratio(op, "scipy"), lambda v: v >= 2)
    for op in RIGID_OPS:
        check(f"N=1 {op}: scipy / quatarray >= 1", ratio(op, "scipy", n=1), lambda v: v >= 1)
    # earlier targets that still hold
    check("product: scipy r1*r2 / quatarray >= 20", ratio("product", "scipy"), lambda v: v >= 20)
    check("apply: scipy / quatarray >= 2", ratio("apply", "scipy"), lambda v: v >= 2)
    for op in ("inv", "magnitude"):
        check(f"{op}: scipy / quatarray >= 1", ratio(op, "scipy"), lambda v: v >= 1)
    check("N=1 product: scipy / quatarray >= 1", ratio("product", "scipy", n=1), lambda v: v >= 1)
    check("N=1 apply: scipy / quatarray >= 1", ratio("apply", "scipy", n=1), lambda v: v >= 1)
    for method in SINGLE_METHODS:
        check(f"N=1 Rotation.{method}: scipy / quatarray >= 1", ratio(f"Rotation {method}", "scipy", n=1),
              lambda v: v >= 1)
    check("N=1 one-query Slerp(t): scipy / quatarray >= 1", ratio("Slerp(t), one query", "scipy", n=1),
          lambda v: v >= 1)
    if imports:
        best, loaded = imports
        check("import quatarray / import numpy (wall, python -c) <= 1.5", best["quatarray"] / best["numpy"],
              lambda v: v <= 1.5)
        out.append(("modules loaded by import quatarray (scipy must not be)", loaded or "[]",
                    "FAIL" if "scipy" in loaded else "PASS"))
    return out


def _versions():
    v = {"python": platform.python_version(), "numpy": np.__version__}
    for lib, mod in (("quatarray", "quatarray"), ("scipy", "scipy"), ("numpy-quaternion", "quaternion"),
                     ("quaternionic", "quaternionic")):
        try:
            v[lib] = __import__(mod).__version__
        except ImportError:
            v[lib] = None
    return v


def machine():
    """CPU model, NumPy's SIMD level and quatarray's threads, as a dict."""
    import os

    import quatarray
    from quatarray import _ops
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            model = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:
        cpus = os.cpu_count()
    return {"cpu": model, "arch": platform.machine(), "simd": _ops.numpy_simd_level(),
            "simd_found": _ops.numpy_simd_found(), "threads": quatarray.get_num_threads(), "cpus": cpus}


def scratch_kept():
    """Bytes of scratch quatarray's threads keep between calls."""
    from quatarray import _blocks
    return _blocks.scratch_bytes()


def _sweep_label(n):
    return "single" if n is None else f"{n:,}".replace(",", " ")


def sweep(repeat=5, min_time=0.02, sizes=None, ops=None, log=print):
    """The size sweep (`benchmarks.sweep`): for each operation and size, scipy's time ÷
    quatarray's, the median over `repeat` interleaved pairs (each the best of a few
    calls lasting at least `min_time`).  Returns {op: {size: ratio}} (None where skipped)."""
    from . import sweep as sw
    sizes = sw.SIZES if sizes is None else sizes
    table = {}
    for name in (ops or sw.OPS):
        table[name] = {}
        for n in sizes:
            try:
                calls = [sw.make(lib, name, n) for lib in ("quatarray", "scipy")]
            except NotImplementedError:
                table[name][n] = None
                continue
            calls[0]()   # warm both (caches, first-call imports)
            calls[1]()
            ratios = []
            for _ in range(repeat):
                best = measure({0: calls[0], 1: calls[1]}, 3, min_time, budget=1.0)
                ratios.append(best[1] / best[0])
            table[name][n] = float(np.median(ratios))
            del calls
        log(f"| {name} | " + " | ".join(_sweep_cell(table[name][n], sw.target(name, n)) for n in sizes) + " |")
    return table


def _sweep_cell(ratio, target):
    """A sweep table's cell: the ratio, in bold where it is below its target."""
    if ratio is None:
        return "-"
    return f"**{ratio:.2f}**" if target is not None and ratio < target else f"{ratio:.2f}"


def _sweep_misses(table):
    """The cells of a sweep below their targets, as lines ``op at size: ratio < target``."""
    from .sweep import target
    return [f"{name} at {_sweep_label(n)}: {r:.2f} < {target(name, n):.2f}"
            for name, row in table.items() for n, r in row.items()
            if r is not None and target(name, n) is not None and r < target(name, n)]


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m benchmarks.compare", description=__doc__.split("\n\n")[0])
    parser.add_argument("--sweep", action="store_true", help="the size sweep table only (scipy ÷ quatarray)")
    parser.add_argument("--quick", action="store_true", help="only the rows the targets need, fewer repeats")
    parser.add_argument("--targets", action="store_true", help="print only the targets table")
    parser.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    parser.add_argument("--repeat", type=int, help="interleaved repeats (default 7, quick 3)")
    args = parser.parse_args(argv)
    if args.sweep:
        from .sweep import SIZES
        mach = machine()
        print(f"# size sweep, {datetime.date.today().isoformat()}: {mach['cpu']}, NumPy SIMD {mach['simd']}, "
              f"{mach['threads']} threads; scipy's time ÷ quatarray's, median of {args.repeat or 5} interleaved pairs")
        print("| method | " + " | ".join(_sweep_label(n) for n in SIZES) + " |")
        print("|---|" + "--:|" * len(SIZES))
        table = sweep(args.repeat or 5)
        misses = _sweep_misses(table)
        print(f"\nBelow target (bold): {len(misses)}" + "".join(f"\n- {m}" for m in misses))
        if args.json:
            with open(args.json, "w") as f:
                json.dump({"machine": mach, "sweep": {op: {_sweep_label(n): r for n, r in row.items()}
                                                      for op, row in table.items()}}, f, indent=1)
        return 0
    repeat = args.repeat or (3 if args.quick or args.targets else 7)
    min_time = 0.01 if args.quick or args.targets else 0.05
    full = not (args.quick or args.targets)
    versions = _versions()
    mach = machine()
    date = datetime.date.today().isoformat()
    say = (lambda s: None) if args.targets else (lambda s: print(s, flush=True))
    title = (f"# quatarray benchmarks, {date}: {mach['cpu']} ({mach['arch']}), NumPy SIMD {mach['simd']}, "
             f"{mach['threads']} threads ({mach['cpus']} CPUs)\n# " + ", ".join(f"{k} {v}" for k, v in versions.items() if v)
             + f"; best of {repeat} interleaved repeats")
    say(title)
    say(header())
    results = run_rows(_rows(full), repeat, min_time, log=say, budget=1.0 if args.quick or args.targets else 3.0)

    from .algebra import Algebra
    from .pairwise import Pairwise
    memory = {}
    for op, cls, call in (("product", Algebra, lambda b: b.lib.product(b.p, b.q)),
                          ("slerp", Pairwise, lambda b: b.lib.slerp(b.q0, b.q1, b.t))):
        try:
            memory[op] = peak_memory(Row(op, cls, None, (BIG, "float64")), call)
        except NotImplementedError:
            pass
    imports = import_times(5 if args.quick or args.targets else 15)

    rows = targets(results, memory, imports)
    if args.targets:
        print(title)
    print(f"\n# targets (N = 1e6, float64 unless said; NumPy SIMD {mach['simd']}, {mach['threads']} threads)")
    width = max(len(r[0]) for r in rows)
    for desc, value, verdict in rows:
        print(f"{desc:<{width}}  {value:>10}  {verdict}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"date": date, "machine": mach, "versions": versions, "repeat": repeat, "results": results,
                       "memory": {k: {"peak": p, "output": s} for k, (p, s) in memory.items()},
                       "imports": {"seconds": imports[0], "loaded": imports[1]},
                       "targets": [dict(target=d, value=v, verdict=x) for d, v, x in rows]}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
