"""Orientation time series: keyframe reduction within a tolerance, integration, differentiation.

asv classes time them at sizes asv can repeat; run as a script for the issue's size::

    python -m benchmarks.timeseries [T] [tracks] [methods]   # default 10^6 x 50, linear,slerp,squad

which prints, per method, the seconds `quatarray.reduce_keys` takes (wall and CPU), the keys kept, the
largest error reached (the tolerance is 0.1 degrees) and, on Linux, the peak resident memory during the
call (the input included).
"""

import sys
import time

import numpy as np

from ._common import rng

METHODS = ["slerp", "squad"]


def capture(T, tracks, dtype="float64", salt=7):
    """(times (T,), keys (T, tracks, 4)): smooth joint-like motions at 120 Hz with 1e-4 rad noise."""
    g = rng(salt)
    t = np.arange(T) / 120.0
    f = g.uniform(0.05, 0.3, (1, tracks, 3))
    phase = g.uniform(0, 6, (1, tracks, 3))
    rotvec = np.sin(2 * np.pi * f * t[:, None, None] + phase) + g.normal(0, 1e-4, (T, tracks, 3))
    half = rotvec / 2
    a = np.linalg.norm(half, axis=-1, keepdims=True)
    q = np.concatenate([np.cos(a), np.sinc(a / np.pi) * half], axis=-1)
    return t, q.astype(dtype)


class ReduceKeys:
    """`quatarray.reduce_keys` at 0.1 degrees (about one key in 10 kept)."""

    params = ([10_000], [10], METHODS, ["float32", "float64"], ["quatarray"])
    param_names = ["samples", "tracks", "method", "dtype", "lib"]

    def setup(self, T, tracks, method, dtype, lib):
        self.t, self.q = capture(T, tracks, dtype)

    def time_reduce(self, T, tracks, method, dtype, lib):
        """Each track reduced on its own (shared=False)."""
        from quatarray import reduce_keys
        reduce_keys(self.t, self.q, 0.1, method=method, degrees=True)

    def time_reduce_shared(self, T, tracks, method, dtype, lib):
        """All tracks on one key grid (shared=True)."""
        from quatarray import reduce_keys
        reduce_keys(self.t, self.q, 0.1, method=method, degrees=True, shared=True)


class AngularVelocity:
    """Integrate angular velocity and differentiate orientations, (T, 10) tracks."""

    params = ([10_000, 1_000_000], ["quatarray"])
    param_names = ["samples", "lib"]

    def setup(self, T, lib):
        self.t, self.q = capture(T // 10, 10)
        self.omega = rng(3).normal(size=(T // 10, 10, 3))

    def time_integrate(self, T, lib):
        """integrate_angular_velocity, fourth-order Magnus."""
        from quatarray import integrate_angular_velocity
        integrate_angular_velocity(self.t, self.omega)

    def time_differentiate(self, T, lib):
        """angular_velocity, seven-point fits."""
        from quatarray import angular_velocity
        angular_velocity(self.t, self.q)


def _reset_peak():
    """Reset the process's peak resident memory (Linux); False where that is not possible."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _peak_gb():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM"):
                return int(line.split()[1]) / 1e6
    return float("nan")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    T = int(float(argv[0])) if argv else 1_000_000
    tracks = int(argv[1]) if len(argv) > 1 else 50
    methods = argv[2].split(",") if len(argv) > 2 else ["linear", "slerp", "squad"]
    from quatarray import reduce_keys
    t, q = capture(T, tracks)
    print(f"reduce_keys, {T:,} samples x {tracks} tracks, tolerance 0.1 deg")
    for method in methods:
        # peak resident memory during the call (the input counts: it is resident throughout)
        peak = _reset_peak()
        start, cpu = time.perf_counter(), time.process_time()
        tracks_out, err = reduce_keys(t, q, 0.1, method=method, degrees=True)
        elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
        kept = sum(len(tr) for tr in tracks_out)
        # CPU seconds (all threads) beside wall seconds: on a shared machine the wall time
        # also counts the other sessions' load
        print(f"  {method:<7} {elapsed:7.1f} s (CPU {cpu:.1f} s)   keys kept {kept:,} of {T * tracks:,} "
              f"({kept / (T * tracks):.1%})   max error {float(err.max()):.4f} deg"
              + (f"   peak RSS {_peak_gb():.2f} GB (input {q.nbytes / 1e9:.2f} GB)" if peak else ""), flush=True)
        del tracks_out


if __name__ == "__main__":
    main()
