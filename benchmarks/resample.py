"""The ``quatarray resample`` command at scale: file in, file out, twice the frame rate.

Cases: an NPZ of 10⁵ keys × 30 tracks, and a BVH of 10⁴ frames × 60 joints
(ZXY Euler channels), both resampled from 30 to 60 frames per second with
slerp.  The scipy twin is the script a scipy user would write for the same
files: load, one `Slerp` per track (scipy's takes a single track), save.
"""

import os

import numpy as np

from ._common import Skip, adapter, rng

#: (keys or frames, tracks or joints) per case.
SCALE = {"npz": (100_000, 30), "bvh": (10_000, 60)}
FPS = 30.0
LIBS = ["quatarray", "scipy"]


def write_inputs(folder):
    """Write the seeded input files of every case into `folder`; return their paths."""
    paths = {}
    k, n = SCALE["npz"]
    times = np.arange(k) / FPS
    steps = rng(51).normal(0, 0.05, (k, n, 3))
    half = np.cumsum(steps, axis=0) / 2  # a smooth random walk of rotation vectors
    a = np.linalg.norm(half, axis=-1, keepdims=True)
    keys = np.concatenate([np.cos(a), np.sinc(a / np.pi) * half], axis=-1)
    paths["npz"] = os.path.join(folder, "tracks.npz")
    np.savez(paths["npz"], times=times, keys=keys)
    k, n = SCALE["bvh"]
    paths["bvh"] = os.path.join(folder, "motion.bvh")
    with open(paths["bvh"], "w") as f:
        f.write(bvh_hierarchy(n))
        f.write(f"MOTION\nFrames: {k}\nFrame Time: {1 / FPS:.8f}\n")
        np.savetxt(f, bvh_frames(k, n), fmt="%.5f")
    return paths


def bvh_hierarchy(n):
    """A root with 6 channels and n - 1 child joints with ZXY rotation channels."""
    lines = ["HIERARCHY", "ROOT Hips", "{", "  OFFSET 0.0 0.0 0.0",
             "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for j in range(1, n):
        lines += [f"  JOINT J{j}", "  {", f"    OFFSET 0.0 {j:.1f} 0.0", "    CHANNELS 3 Zrotation Xrotation Yrotation",
                  "    End Site", "    {", "      OFFSET 0.0 1.0 0.0", "    }", "  }"]
    lines.append("}")
    return "\n".join(lines) + "\n"


def bvh_frames(k, n):
    """Smooth motion: positions and ZXY angles (degrees, |X| < 80) as sums of sines."""
    g = rng(52)
    t = np.arange(k)[:, None] / FPS
    amp = g.uniform(5, 80, 3 + 3 * n)
    freq = g.uniform(0.1, 1.5, 3 + 3 * n)
    phase = g.uniform(0, 2 * np.pi, 3 + 3 * n)
    return amp * np.sin(2 * np.pi * freq * t + phase)


def scipy_resample_npz(src, dst, fps):
    """NPZ resampling with scipy: one `Slerp` per track."""
    from scipy.spatial.transform import Rotation, Slerp
    with np.load(src) as f:
        times, keys = f["times"], f["keys"]
    t = times[0] + np.arange(int(np.floor((times[-1] - times[0]) * fps + 1e-9)) + 1) / fps
    flat = keys.reshape(len(times), -1, 4)
    out = np.empty((len(t),) + flat.shape[1:])
    for j in range(flat.shape[1]):
        r = Slerp(times, Rotation.from_quat(flat[:, j], scalar_first=True))(t)
        out[:, j] = r.as_quat(scalar_first=True)
    np.savez(dst, times=t, keys=out.reshape((len(t),) + keys.shape[1:]))


def scipy_resample_bvh(src, dst, fps):
    """BVH resampling with scipy, for this file's layout (root 6 channels, then ZXY per joint)."""
    from scipy.spatial.transform import Rotation, Slerp
    with open(src) as f:
        text = f.read()
    head, motion = text.split("MOTION\n", 1)
    lines = motion.split("\n", 2)
    frame_time = float(lines[1].split(":")[1])
    frames = np.loadtxt(lines[2].splitlines())
    k = len(frames)
    times = np.arange(k) * frame_time
    t = np.arange(int(np.floor(times[-1] * fps + 1e-9)) + 1) / fps
    out = np.empty((len(t), frames.shape[1]))
    for c in range(3):
        out[:, c] = np.interp(t, times, frames[:, c])
    angles = frames[:, 3:].reshape(k, -1, 3)
    for j in range(angles.shape[1]):
        r = Slerp(times, Rotation.from_euler("ZXY", angles[:, j], degrees=True))(t)
        out[:, 3 + 3 * j: 6 + 3 * j] = r.as_euler("ZXY", degrees=True)
    with open(dst, "w") as f:
        f.write(head + f"MOTION\nFrames: {len(t)}\nFrame Time: {1 / fps:.8f}\n")
        np.savetxt(f, out, fmt="%.5f")


class Resample:
    """Resample a file to twice its frame rate with slerp (read, interpolate, write)."""

    params = (["npz", "bvh"], LIBS)
    param_names = ["case", "lib"]
    timeout = 300

    def setup_cache(self):
        """Write the input files once (asv runs this in a scratch folder)."""
        return write_inputs(os.path.abspath("."))

    def setup(self, paths, case, lib):
        adapter(lib)  # NotImplementedError when the library is missing
        self.src = paths[case]
        self.dst = os.path.join(os.path.dirname(self.src), f"out-{lib}.{case}")
        if lib == "quatarray":
            try:
                from quatarray.formats import resample_file
            except ImportError as exc:
                raise NotImplementedError(f"quatarray.formats is not available ({exc})") from None
            self.run = lambda: resample_file(self.src, self.dst, fps=2 * FPS, method="slerp", force=True)
        else:
            twin = scipy_resample_npz if case == "npz" else scipy_resample_bvh
            self.run = lambda: twin(self.src, self.dst, 2 * FPS)

    def time_resample(self, paths, case, lib):
        """Read, resample to 2× the frames with slerp, write (quatarray: ``resample_file``)."""
        self.run()

    def peakmem_resample(self, paths, case, lib):
        """Peak memory of quatarray's resampling run (scipy's twin is skipped: its 5-11 s per
        run would cost asv --quick a sixth of its 5 minutes, and no target reads it)."""
        if lib != "quatarray":
            raise Skip("peak memory of quatarray's run only")
        self.run()

