"""Cost per element of the NumPy ufuncs the kernels choose between, on this machine.

Usage::

    python -m benchmarks.ufuncs          # markdown table, float64 and float32

Each ufunc runs on one block of `quatarray._blocks.BLOCK` elements held in
cache (as inside the kernels), interleaved with the others, best of many
rounds: on a shared machine the minimum is the cost, the rest is noise.
The header names NumPy's SIMD level (X86_V4 = AVX-512, X86_V3 = AVX2): the
transcendental loops differ most between the two (benchmarks/README.md).
"""

import sys
import time

import numpy as np

__all__ = ["costs", "main"]


def _ops(dtype, n):
    rng = np.random.default_rng(0)
    x = rng.uniform(-1.5, 1.5, n).astype(dtype)
    y = rng.uniform(0.2, 1.5, n).astype(dtype)
    s = (x / 1.5).astype(dtype)
    o = np.empty(n, dtype)
    from quatarray import _trig
    quarter = (x * (np.pi / 6)).astype(dtype)   # within [-π/4, π/4]
    rows = np.empty((3, n), dtype)
    ops = {
        "arctan2": lambda: np.arctan2(x, y, out=o), "arctan": lambda: np.arctan(x, out=o),
        "tan": lambda: np.tan(x, out=o), "sin": lambda: np.sin(x, out=o), "cos": lambda: np.cos(x, out=o),
        "arcsin": lambda: np.arcsin(s, out=o), "arccos": lambda: np.arccos(s, out=o),
        "hypot": lambda: np.hypot(x, y, out=o), "log": lambda: np.log(y, out=o),
        "log1p": lambda: np.log1p(y, out=o), "exp": lambda: np.exp(x, out=o),
        "sqrt": lambda: np.sqrt(y, out=o), "divide": lambda: np.divide(x, y, out=o),
        "multiply": lambda: np.multiply(x, y, out=o), "add": lambda: np.add(x, y, out=o),
    }
    # quatarray's own functions (`quatarray._trig`), whatever this CPU would pick
    if dtype == np.float64:
        ops["tan, quatarray rational (x in ±π/4)"] = lambda: _trig.rational(quarter, o, *rows)
        ops["tan, quatarray reduced (x in ±1.5)"] = lambda: _trig.reduced(x, o, rows)
    else:
        unit = np.abs(s)
        ops["arctan, quatarray on [0, 1]"] = lambda: _trig.atan_unit32(unit, o, *rows)
    return ops


def costs(dtype, rounds=40, calls=10):
    """{ufunc name: best ns per element} for `dtype` on one in-cache block."""
    from quatarray._blocks import BLOCK
    ops = _ops(dtype, BLOCK)
    best = dict.fromkeys(ops, float("inf"))
    for _ in range(rounds):
        for name, f in ops.items():
            t0 = time.perf_counter()
            for _ in range(calls):
                f()
            best[name] = min(best[name], (time.perf_counter() - t0) / calls / BLOCK * 1e9)
    return best


def main(argv=None):
    from .compare import machine
    m = machine()
    print(f"# ns per element, one in-cache block; {m['cpu']}, NumPy {np.__version__}, SIMD {m['simd']}\n")
    c64, c32 = costs(np.float64), costs(np.float32)
    print("| ufunc | float64 | float32 |")
    print("|---|---|---|")
    for name in {**c64, **c32}:
        cells = [f"{c[name]:.2f}" if name in c else "–" for c in (c64, c32)]
        print(f"| {name} | {cells[0]} | {cells[1]} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
