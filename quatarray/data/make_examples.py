"""Regenerate the example files in this folder (run once; the output is committed).

    python quatarray/data/make_examples.py

- ``arm.csv``: a shoulder, elbow and wrist track, 11 keys at unequal times
  over 4 s (scalar-first quaternions).
- ``walk.bvh``: a 10-joint skeleton walking, 13 frames at 8 fps, with three
  different rotation channel orders (ZXY, XYZ, YXZ).
- ``imu.csv``: an orientation log as trackers write it, scalar-last
  (``imu.x, imu.y, imu.z, imu.w``) at irregular times around 30 Hz over 2 s.

Only NumPy is used, with a fixed seed, so the files are reproducible.
"""

import os

import numpy as np


def _quat(axis, deg):
    axis = np.asarray(axis, float)
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    half = np.radians(deg)[..., None] / 2
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)


def _mul(p, q):
    pw, pv, qw, qv = p[..., :1], p[..., 1:], q[..., :1], q[..., 1:]
    return np.concatenate([pw * qw - (pv * qv).sum(-1, keepdims=True),
                           pw * qv + qw * pv + np.cross(pv, qv)], axis=-1)


def arm_csv(rng):
    times = np.array([0.0, 0.3, 0.55, 1.0, 1.4, 1.6, 2.2, 2.75, 3.1, 3.7, 4.0])
    s = times / 4.0
    # shoulder: a reach forward and up, then a sweep across the body and back
    lift = _quat([0, 0, 1], 70 * np.sin(np.pi * s) + rng.normal(0, 4, len(s)))
    sweep = _quat([0, 1, 0], 60 * np.sin(2 * np.pi * s) + rng.normal(0, 4, len(s)))
    twist = _quat([1, 0, 0], 25 * np.cos(3 * np.pi * s))
    shoulder = _mul(_mul(sweep, lift), twist)
    # elbow: a hinge opening and closing
    elbow = _quat(np.broadcast_to([1, 0, 0], (len(s), 3)), 70 + 55 * np.sin(3 * np.pi * s + 0.4))
    # wrist: small flexion and deviation
    wrist = _mul(_quat([0, 0, 1], 30 * np.sin(5 * s + 1) + rng.normal(0, 3, len(s))),
                 _quat([0, 1, 0], 15 * np.cos(4 * s)))
    keys = np.stack([shoulder, elbow, wrist], axis=1)
    keys *= np.where(keys[..., :1] < 0, -1, 1)  # w >= 0, as most exporters write
    keys /= np.linalg.norm(keys, axis=-1, keepdims=True)
    lines = ["time," + ",".join(f"{n}.{c}" for n in ("shoulder", "elbow", "wrist") for c in "wxyz")]
    for t, k in zip(times, keys.reshape(len(times), -1)):
        lines.append(f"{t:g}," + ",".join(f"{v:.9f}" for v in k))
    return "\n".join(lines) + "\n"


JOINTS = [  # name, parent depth, offset, channel order
    ("Hips", 0, (0, 0, 0), "ZXY"),
    ("Spine", 1, (0, 10.0, 0), "ZXY"),
    ("Head", 2, (0, 25.0, 0), "ZXY"),
    ("LeftArm", 2, (16.0, 20.0, 0), "XYZ"),
    ("LeftForeArm", 3, (0, -27.0, 0), "XYZ"),
    ("RightArm", 2, (-16.0, 20.0, 0), "YXZ"),
    ("LeftUpLeg", 1, (9.0, -3.0, 0), "ZXY"),
    ("LeftLeg", 2, (0, -42.0, 0), "ZXY"),
    ("RightUpLeg", 1, (-9.0, -3.0, 0), "ZXY"),
    ("RightLeg", 2, (0, -42.0, 0), "ZXY"),
]


def walk_bvh(rng):
    fps, n = 8, 13
    t = np.arange(n) / fps
    ph = 2 * np.pi * t / 1.0  # one stride per second
    deg = {  # per joint: angles about X, Y, Z (degrees)
        "Hips": (3 * np.sin(2 * ph), 8 * np.sin(ph), 4 * np.cos(ph)),
        "Spine": (5 + 2 * np.sin(2 * ph), -6 * np.sin(ph), -3 * np.cos(ph)),
        "Head": (-4 + 2 * np.sin(2 * ph + 1), 5 * np.sin(ph), 2 * np.cos(ph)),
        "LeftArm": (-25 * np.sin(ph), 10 + 0 * ph, -75 + 5 * np.cos(ph)),
        "LeftForeArm": (-20 - 15 * np.sin(ph + 0.5), 0 * ph, 0 * ph),
        "RightArm": (25 * np.sin(ph), -10 + 0 * ph, 75 - 5 * np.cos(ph)),
        "LeftUpLeg": (30 * np.sin(ph), 3 * np.sin(ph), 2 + 0 * ph),
        "LeftLeg": (30 + 30 * np.sin(ph - 1.2), 0 * ph, 0 * ph),
        "RightUpLeg": (-30 * np.sin(ph), -3 * np.sin(ph), -2 + 0 * ph),
        "RightLeg": (30 - 30 * np.sin(ph - 1.2), 0 * ph, 0 * ph),
    }
    hierarchy, columns = ["HIERARCHY"], []
    depth = 0
    for i, (name, d, off, order) in enumerate(JOINTS):
        while depth > d:
            depth -= 1
            hierarchy.append("\t" * depth + "}")
        pad = "\t" * d
        hierarchy.append(pad + ("ROOT " if d == 0 else "JOINT ") + name)
        hierarchy.append(pad + "{")
        hierarchy.append(pad + "\tOFFSET " + " ".join(f"{v:.2f}" for v in off))
        chans = [f"{a}rotation" for a in order]
        if d == 0:
            chans = ["Xposition", "Yposition", "Zposition"] + chans
            columns += [0.5 * np.sin(ph), 92 + 1.5 * np.cos(2 * ph), 120 * t]
        hierarchy.append(pad + f"\tCHANNELS {len(chans)} " + " ".join(chans))
        xyz = dict(zip("XYZ", deg[name]))
        columns += [xyz[a] + rng.normal(0, 0.3, n) for a in order]
        last = i + 1 == len(JOINTS) or JOINTS[i + 1][1] <= d
        if last:
            hierarchy += [pad + "\tEnd Site", pad + "\t{", pad + "\t\tOFFSET 0.00 -5.00 0.00", pad + "\t}"]
        depth = d + 1
    while depth > 0:
        depth -= 1
        hierarchy.append("\t" * depth + "}")
    frames = np.stack(columns, axis=1)
    motion = ["MOTION", f"Frames: {n}", f"Frame Time: {1 / fps}"]
    motion += [" ".join(f"{v:.4f}" for v in row) for row in frames]
    return "\n".join(hierarchy + motion) + "\n"


def imu_csv(rng):
    times = np.round(np.cumsum(np.r_[0.0, rng.uniform(0.025, 0.042, 59)]), 4)
    yaw = _quat([0, 0, 1], 40 * np.sin(1.7 * times) + 10 * times)
    pitch = _quat([0, 1, 0], 12 * np.sin(3.1 * times + 0.3))
    roll = _quat([1, 0, 0], 6 * np.cos(2.3 * times))
    q = _mul(_mul(yaw, pitch), roll)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    lines = ["time,imu.x,imu.y,imu.z,imu.w"]
    lines += [f"{t:.4f}," + ",".join(f"{v:.6f}" for v in np.roll(k, -1)) for t, k in zip(times, q)]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    here = os.path.dirname(os.path.abspath(__file__))
    rng = np.random.default_rng(6)
    with open(os.path.join(here, "arm.csv"), "w", newline="\n") as f:
        f.write(arm_csv(rng))
    with open(os.path.join(here, "walk.bvh"), "w", newline="\n") as f:
        f.write(walk_bvh(rng))
    with open(os.path.join(here, "imu.csv"), "w", newline="\n") as f:
        f.write(imu_csv(rng))
