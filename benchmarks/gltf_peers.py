"""Keys kept and error reached: ``quatarray reduce`` against glTF-Transform's ``resample`` and gltfpack.

A benchmark, not a test: it runs the JavaScript / C++ tools when they are
installed (``npm install -g @gltf-transform/cli gltfpack``, or a local prefix
given with ``--bin DIR``) and prints, per clip, the rotation keys each tool
keeps and the largest angle between its curve (LINEAR, i.e. slerp) and the
original keys, measured at every original key time.  quatarray is then run at
the error each tool actually reached, so that the key counts compare at equal
error::

    python -m benchmarks.gltf_peers [--bin node_modules/.bin] [--tolerance 1e-3]

The clips: the shipped arm (3 joints) resampled at 120 Hz, and a synthetic
capture of 20 joints x 1200 frames at 120 Hz (`benchmarks.timeseries.capture`).
"""

import argparse
import os
import shutil
import subprocess
import tempfile

import numpy as np

from quatarray import Track
from quatarray.formats import Keyframes, example_path, keyframes_to_gltf, read_csv, resample_file
from quatarray.formats.gltf_read import read_animations, read_gltf
from quatarray.formats.reduce import reduce_file

from .timeseries import capture


def _rotation_samplers(path):
    """{node index: (times, keys (K, 4) scalar-first)} of the LINEAR rotation samplers."""
    gf = read_gltf(path)
    out = {}
    for a, samplers in enumerate(read_animations(gf)):
        for channel in gf.json["animations"][a].get("channels", []):
            s = samplers[channel["sampler"]]
            if s.path == "rotation":
                values = s.values if s.interpolation != "CUBICSPLINE" else s.values.reshape(len(s.times), 3, 4)[:, 1]
                out[channel["target"]["node"]] = (s.times, np.roll(values, 1, axis=-1), s.interpolation)
    return out


def _angles(p, q):
    p = p / np.linalg.norm(p, axis=-1, keepdims=True)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    s = np.where(np.sum(p * q, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    return 4 * np.arctan2(np.linalg.norm(p - s * q, axis=-1), np.linalg.norm(p + s * q, axis=-1))


def keys_and_error(original, reduced):
    """(rotation keys in `reduced`, largest error at the original key times, radians)."""
    ref, out = _rotation_samplers(original), _rotation_samplers(reduced)
    keys, err = 0, 0.0
    for node, (t, q, _) in ref.items():
        if node not in out:          # a track dropped as constant: it holds the node's rest pose
            continue
        tr, qr, interp = out[node]
        keys += len(tr)
        if len(tr) == 1:
            curve = np.broadcast_to(qr[0], q.shape)
        else:
            method = "slerp" if interp != "STEP" else "linear"
            curve = np.asarray(Track(tr, qr, method=method, extrapolate="clamp")(t))
        err = max(err, float(_angles(curve, q).max()))
    return keys, err


def clips(folder):
    arm = os.path.join(folder, "arm.glb")
    keyframes_to_gltf(arm, read_csv(example_path("arm.csv")))
    arm120 = os.path.join(folder, "arm_120.glb")
    resample_file(arm, arm120, fps=120, method="squad")
    t, q = capture(1200, 20)
    synth = os.path.join(folder, "capture_20x1200.glb")
    keyframes_to_gltf(synth, Keyframes(t, q, tuple(f"joint{j}" for j in range(20))))
    return [arm120, synth]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin", help="folder holding gltf-transform and gltfpack (default: PATH)")
    parser.add_argument("--tolerance", type=float, default=1e-3, help="glTF-Transform's --tolerance")
    args = parser.parse_args(argv)

    def tool(name):
        return shutil.which(name, path=args.bin) if args.bin else shutil.which(name)

    with tempfile.TemporaryDirectory() as folder:
        for clip in clips(folder):
            total, _ = keys_and_error(clip, clip)
            print(f"{os.path.basename(clip)}: {total} rotation keys")
            runs = []
            if tool("gltf-transform"):
                out = os.path.join(folder, "gt.glb")
                subprocess.run([tool("gltf-transform"), "resample", clip, out, "--tolerance", str(args.tolerance)],
                               check=True, capture_output=True)
                runs.append((f"glTF-Transform resample --tolerance {args.tolerance:g}", out))
            if tool("gltfpack"):
                out = os.path.join(folder, "pack.glb")
                subprocess.run([tool("gltfpack"), "-i", clip, "-o", out, "-noq", "-ac"], check=True,
                               capture_output=True)
                runs.append(("gltfpack -noq (resampled at 30 Hz)", out))
            if not runs:
                print("  neither gltf-transform nor gltfpack found (npm install -g @gltf-transform/cli gltfpack)")
            for label, out in runs:
                keys, err = keys_and_error(clip, out)
                ours = os.path.join(folder, "ours.glb")
                reduce_file(clip, ours, max(err, 1e-9))
                our_keys, our_err = keys_and_error(clip, ours)
                print(f"  {label:<44} {keys:>6} keys ({keys / total:6.1%}), max error {np.degrees(err):.4f} deg")
                print(f"  {'quatarray reduce at that error':<44} {our_keys:>6} keys ({our_keys / total:6.1%}), "
                      f"max error {np.degrees(our_err):.4f} deg")


if __name__ == "__main__":
    main()
