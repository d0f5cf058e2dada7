"""glTF 2.0 animations (quatarray.formats.gltf, quatarray.formats.gltf_sampler, ``quatarray resample`` on .gltf / .glb).

The input files are built here with pygltflib; the outputs are read back with
pygltflib and a few lines of NumPy written here, and compared with the
spec's interpolation formulas written out again below, one query at a time.
"""

import base64
import errno
import json
import os
import re
import shutil
import struct
import subprocess
import sys

import numpy as np
import pytest

pygltflib = pytest.importorskip("pygltflib", reason="the glTF tests need pygltflib (pip install 'quatarray[gltf]')")

from quatarray import cli  # noqa: E402
from quatarray.formats import keyframes_to_gltf, resample_gltf  # noqa: E402
from quatarray.formats.gltf_read import read_accessor, read_gltf  # noqa: E402
from quatarray.formats.gltf_sampler import evaluate_sampler  # noqa: E402
from quatarray.formats import example_path, read_csv  # noqa: E402
from quatarray.formats.reduce import reduce_file  # noqa: E402
from quatarray.interpolate import Track  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
SIZES = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}
F32 = 5126
EPS32 = float(np.finfo(np.float32).eps)


# --------------------------------------------------------------------------- building files with pygltflib

class Builder:
    """A glTF document built with pygltflib, its data collected in one buffer."""

    def __init__(self):
        self.g = pygltflib.GLTF2(asset=pygltflib.Asset(version="2.0", generator="quatarray tests"))
        self.blob = bytearray()

    def view(self, data, **kw):
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.g.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(data), **kw))
        self.blob += data
        return len(self.g.bufferViews) - 1

    def accessor(self, values, kind, ctype=F32, normalized=False, bounds=False, **kw):
        a = np.asarray(values, DTYPES[ctype]).reshape(-1, SIZES[kind])
        acc = pygltflib.Accessor(bufferView=self.view(a.tobytes()), componentType=ctype, count=len(a), type=kind,
                                 normalized=normalized or None, **kw)
        if bounds:
            acc.min, acc.max = a.min(axis=0).tolist(), a.max(axis=0).tolist()
        self.g.accessors.append(acc)
        return len(self.g.accessors) - 1

    def sampler(self, anim, times, values, kind, interpolation="LINEAR", ctype=F32, normalized=False):
        anim.samplers.append(pygltflib.AnimationSampler(
            input=self.accessor(times, "SCALAR", bounds=True), interpolation=interpolation,
            output=self.accessor(values, kind, ctype, normalized)))
        return len(anim.samplers) - 1

    def channel(self, anim, node, path, *args, **kw):
        s = self.sampler(anim, *args, **kw)
        anim.channels.append(pygltflib.AnimationChannel(sampler=s, target=pygltflib.AnimationChannelTarget(
            node=node, path=path)))

    def save(self, path, layout="glb"):
        """Write as GLB, .gltf with a data URI, or .gltf with an external .bin; return the document dict."""
        g, data = self.g, bytes(self.blob)
        if layout == "glb":
            g.buffers = [pygltflib.Buffer(byteLength=len(data))]
            g.set_binary_blob(data)
            g.save_binary(str(path))
            return json.loads(g.to_json())
        if layout == "embedded":
            uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
        else:
            uri = os.path.splitext(os.path.basename(path))[0] + "_data.bin"
            with open(os.path.join(os.path.dirname(path), uri), "wb") as f:
                f.write(data)
        g.buffers = [pygltflib.Buffer(byteLength=len(data), uri=uri)]
        doc = json.loads(g.gltf_to_json())
        with open(path, "w") as f:
            json.dump(doc, f)
        return doc


def unit(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def skinned(rng):
    """A skinned-looking file: a joint chain, a skinned mesh with two morph targets, two animations.

    Returns the builder and, per animation, its channels as
    ``(node, path, times, values (K or 3K, n), interpolation)``.
    """
    b = Builder()
    g = b.g
    g.nodes = [pygltflib.Node(name="root", children=[1]),
               pygltflib.Node(name="hips", children=[2], translation=[0, 1, 0]),
               pygltflib.Node(name="spine", children=[3], translation=[0, 0.3, 0], extras={"joint": "spine"}),
               pygltflib.Node(name="head", translation=[0, 0.4, 0]),
               pygltflib.Node(name="body", mesh=0, skin=0)]
    g.scenes = [pygltflib.Scene(nodes=[0, 4])]
    g.scene = 0
    times = np.array([0.0, 0.25, 0.6, 1.0], np.float32)
    rot = unit(rng, 4)
    rot[2] *= -1 if rot[2] @ rot[1] > 0 else 1          # a key on the long way round: slerp must take the short one
    cubic_rot = np.concatenate([rng.normal(scale=0.5, size=(4, 1, 4)), unit(rng, 4)[:, None],
                                rng.normal(scale=0.5, size=(4, 1, 4))], axis=1).reshape(12, 4)
    cubic_vec = rng.normal(size=(12, 3))
    walk = pygltflib.Animation(name="walk", extras={"take": 3})
    channels = [(1, "translation", times, rng.normal(size=(4, 3)), "LINEAR"),
                (1, "rotation", times, rot, "LINEAR"),
                (1, "scale", times, 1 + rng.random((4, 3)), "STEP"),
                (2, "rotation", times, cubic_rot, "CUBICSPLINE"),
                (2, "translation", times, cubic_vec, "CUBICSPLINE"),
                (3, "rotation", times, unit(rng, 4), "STEP"),
                (4, "weights", times, rng.random((4, 2)), "LINEAR")]
    for node, path, t, v, interp in channels:     # animation data first: the mesh's accessors get renumbered
        b.channel(walk, node, path, t, v, {"rotation": "VEC4", "weights": "SCALAR"}.get(path, "VEC3"), interp)
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    attrs = pygltflib.Attributes(
        POSITION=b.accessor(pos, "VEC3", bounds=True),
        JOINTS_0=b.accessor([[0, 1, 2, 0]] * 3, "VEC4", ctype=5121),
        WEIGHTS_0=b.accessor([[0.5, 0.25, 0.25, 0]] * 3, "VEC4"))
    targets = [pygltflib.Attributes(POSITION=b.accessor(pos * s, "VEC3", bounds=True)) for s in (0.1, -0.2)]
    prim = pygltflib.Primitive(attributes=attrs, indices=b.accessor([0, 1, 2], "SCALAR", ctype=5123),
                               targets=targets)
    g.meshes = [pygltflib.Mesh(primitives=[prim], weights=[0.0, 0.0], name="body")]
    g.skins = [pygltflib.Skin(joints=[1, 2, 3], inverseBindMatrices=b.accessor(np.tile(np.eye(4), (3, 1)), "MAT4"))]
    wave_times = np.array([0.1, 0.3, 0.5], np.float32)
    wave = pygltflib.Animation(name="wave")
    wave_channels = [(4, "weights", wave_times, rng.random((9, 2)), "CUBICSPLINE"),
                     (3, "rotation", wave_times[:2], unit(rng, 2), "LINEAR")]     # ends before the others
    for node, path, t, v, interp in wave_channels:
        b.channel(wave, node, path, t, v, "SCALAR" if path == "weights" else "VEC4", interp)
    g.animations = [walk, wave]
    return b, [channels, wave_channels]


# --------------------------------------------------------------------------- reading outputs independently

def load(path):
    """(document dict, buffer bytes) of a written file, read with pygltflib and checked structurally."""
    g = pygltflib.GLTF2.load(str(path))
    with open(path, "rb") as f:
        raw = f.read()
    if raw[:4] == b"glTF":
        doc = json.loads(raw[20:20 + struct.unpack_from("<I", raw, 12)[0]])
    else:
        doc = json.loads(raw)
    data = [g.get_data_from_buffer_uri(buf.uri) for buf in g.buffers]
    check_structure(doc, data, raw)
    return doc, data


def decode(doc, data, index):
    """Accessor `index` as float64 (count, n), tightly packed or strided, normalized per the spec."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    dt, n = np.dtype(DTYPES[acc["componentType"]]), SIZES[acc["type"]]
    stride = view.get("byteStride", dt.itemsize * n)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    rows = [np.frombuffer(data[view["buffer"]], dt, n, start + k * stride) for k in range(acc["count"])]
    out = np.array(rows, np.float64)
    if acc.get("normalized"):
        out = np.maximum(out / float(np.iinfo(dt).max), -1.0)
    return out


def check_structure(doc, data, raw):
    """The structural rules of the spec that a writer can break."""
    assert doc["asset"]["version"] == "2.0"
    for b, buf in enumerate(doc.get("buffers", [])):
        assert buf["byteLength"] <= len(data[b])
    for view in doc.get("bufferViews", []):
        assert view["byteOffset"] % 4 == 0
        assert view["byteOffset"] + view["byteLength"] <= doc["buffers"][view["buffer"]]["byteLength"]
    for acc in doc.get("accessors", []):
        view = doc["bufferViews"][acc["bufferView"]]
        size = np.dtype(DTYPES[acc["componentType"]]).itemsize
        stride = view.get("byteStride", size * SIZES[acc["type"]])
        assert (view["byteOffset"] + acc.get("byteOffset", 0)) % size == 0
        assert acc.get("byteOffset", 0) + stride * (acc["count"] - 1) + size * SIZES[acc["type"]] <= view["byteLength"]
    for anim in doc.get("animations", []):
        for s in anim["samplers"]:
            times = decode(doc, data, s["input"])[:, 0]
            acc = doc["accessors"][s["input"]]
            assert acc["min"] == [times.min()] and acc["max"] == [times.max()]
            assert (np.diff(times) > 0).all()
            out = doc["accessors"][s["output"]]
            per = 3 if s.get("interpolation") == "CUBICSPLINE" else 1
            assert out["count"] % (per * len(times)) == 0
        for c in anim["channels"]:
            if c["target"]["path"] != "weights":
                s = anim["samplers"][c["sampler"]]
                assert doc["accessors"][s["output"]]["count"] == doc["accessors"][s["input"]]["count"]
    if raw[:4] == b"glTF":
        magic, version, length = struct.unpack_from("<4sII", raw)
        assert (version, length) == (2, len(raw))
        jlen, jtype = struct.unpack_from("<II", raw, 12)
        assert jtype == 0x4E4F534A and jlen % 4 == 0
        if len(raw) > 20 + jlen:
            blen, btype = struct.unpack_from("<II", raw, 20 + jlen)
            assert btype == 0x004E4942 and blen % 4 == 0 and 28 + jlen + blen == len(raw)


def channel_output(doc, data, anim, node, path):
    """(times, values (M, n)) written for the channel targeting node/path in animation `anim`."""
    a = doc["animations"][anim]
    (c,) = [c for c in a["channels"] if c["target"] == {"node": node, "path": path}]
    s = a["samplers"][c["sampler"]]
    times = decode(doc, data, s["input"])[:, 0]
    return times, decode(doc, data, s["output"]).reshape(len(times), -1), s["interpolation"]


# --------------------------------------------------------------------------- the spec's formulas, one query at a time

def spec_value(times, values, interpolation, t, rotation):
    """glTF 2.0 Appendix C for one query time t, written out plainly."""
    times = [float(x) for x in times]
    K = len(times)
    t = min(max(t, times[0]), times[-1])
    k = max(j for j in range(K) if times[j] <= t)
    if rotation and interpolation != "CUBICSPLINE":   # keys are unit quaternions (to float32 precision)
        values = values / np.linalg.norm(values, axis=-1, keepdims=True)
    key = (lambda j: values[3 * j + 1]) if interpolation == "CUBICSPLINE" else (lambda j: values[j])
    if interpolation == "STEP" or k == K - 1:
        v = key(k)
        return v / np.linalg.norm(v) if rotation else v
    td = times[k + 1] - times[k]
    s = (t - times[k]) / td
    if interpolation == "LINEAR":
        a, b = values[k], values[k + 1]
        if not rotation:
            return a * (1 - s) + b * s
        d = float(a @ b)
        if d < 0:
            b, d = -b, -d
        theta = np.arccos(min(d, 1.0))
        if theta < 1e-6:
            return a
        return (np.sin((1 - s) * theta) * a + np.sin(s * theta) * b) / np.sin(theta)
    p0, m0 = values[3 * k + 1], td * values[3 * k + 2]
    p1, m1 = values[3 * k + 4], td * values[3 * k + 3]
    v = ((2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * m0
         + (-2 * s**3 + 3 * s**2) * p1 + (s**3 - s**2) * m1)
    return v / np.linalg.norm(v) if rotation else v


def assert_close(got, want, rotation, atol):
    got, want = np.asarray(got), np.asarray(want)
    if rotation:   # q and -q are the same rotation
        want = want * np.where(np.sum(got * want, axis=-1) < 0, -1.0, 1.0)[..., None]
    np.testing.assert_allclose(got, want, rtol=0, atol=atol)


def run(*args, cwd=None):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [ROOT, env.get("PYTHONPATH")]))
    return subprocess.run([sys.executable, "-m", "quatarray", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=120)


@pytest.fixture
def rng():
    return np.random.default_rng(20261123)


# --------------------------------------------------------------------------- evaluation as the spec says

@pytest.mark.parametrize("layout", ["glb", "embedded", "external"])
def test_every_channel_follows_the_spec(tmp_path, rng, layout):
    b, animations = skinned(rng)
    src = tmp_path / ("in.glb" if layout == "glb" else "in.gltf")
    b.save(src, layout)
    dst = tmp_path / ("out.glb" if layout == "glb" else "out.gltf")
    nkeys, nframes = resample_gltf(src, dst, fps=24)
    doc, data = load(dst)
    assert (nkeys, nframes) == (4 + 3, 25 + 10)     # walk: 0..1 s at 24 fps; wave: 0.1..0.5 s
    for a, channels in enumerate(animations):
        for node, path, times, values, interp in channels:
            t, got, kind = channel_output(doc, data, a, node, path)
            assert kind == "LINEAR"     # STEP and CUBICSPLINE too: their values at the new keys, written LINEAR
            t0 = min(c[2][0] for c in channels)
            np.testing.assert_allclose(t, t0 + np.arange(len(t)) / 24, rtol=0, atol=4 * EPS32)
            rotation = path == "rotation"
            v32 = np.asarray(values, np.float32).astype(np.float64)
            width = got.shape[1]
            want = [spec_value(times, v32.reshape(-1, width), interp, x, rotation) for x in t]
            assert_close(got, want, rotation, atol=4 * EPS32 * max(1.0, np.abs(v32).max()))
            if rotation:   # unit, and consecutive frames in the same hemisphere (no sign flips between frames)
                np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1, rtol=0, atol=2 * EPS32)
                assert (np.sum(got[1:] * got[:-1], axis=1) >= 0).all()


def test_clamped_outside_the_keys(tmp_path, rng):
    # the 'wave' head rotation has keys on 0.1..0.3 in an animation that lasts 0.1..0.5
    b, animations = skinned(rng)
    b.save(tmp_path / "in.glb")
    resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", fps=50)
    doc, data = load(tmp_path / "out.glb")
    t, got, _ = channel_output(doc, data, 1, 3, "rotation")
    last = np.asarray(animations[1][1][3][-1], np.float32)
    after = t > np.float32(0.3)
    assert after.sum() == 10
    assert_close(got[after], np.broadcast_to(last / np.linalg.norm(last), got[after].shape), True, 4 * EPS32)


def test_clamped_query_times_and_refusals(tmp_path, rng):
    b, animations = skinned(rng)
    b.save(tmp_path / "in.glb")
    with pytest.raises(ValueError, match="outside animation 0's key times .* use extrapolate='clamp'"):
        resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", times=[-0.5, 0.5])
    with pytest.raises(ValueError, match="extrapolate is 'extend'"):
        resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", times=[0.5, 2.0], extrapolate="extend")
    assert not (tmp_path / "out.glb").exists()
    resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", times=[-0.5, 0.5, 2.0], extrapolate="clamp")
    doc, data = load(tmp_path / "out.glb")
    t, got, _ = channel_output(doc, data, 0, 1, "translation")
    node, path, times, values, interp = animations[0][0]
    v32 = np.asarray(values, np.float32).astype(np.float64)
    np.testing.assert_array_equal(t, [-0.5, 0.5, 2.0])
    np.testing.assert_allclose(got, [v32[0], spec_value(times, v32, interp, 0.5, False), v32[-1]],
                               rtol=0, atol=4 * EPS32 * np.abs(v32).max())


@pytest.mark.parametrize("interpolation", ["STEP", "LINEAR", "CUBICSPLINE"])
def test_evaluate_sampler_raw(rng, interpolation):
    times = np.array([0.0, 0.5, 2.0, 2.25])
    per = 3 if interpolation == "CUBICSPLINE" else 1
    values = rng.normal(size=(per * 4, 3))
    rot = unit(rng, per * 4)
    t = np.linspace(-1, 3, 33)
    for vals, rotation in ((values, False), (rot, True)):
        got = evaluate_sampler(times, vals, interpolation, t, rotation)
        want = [spec_value(times, vals, interpolation, x, rotation) for x in t]
        assert_close(got, want, rotation, 1e-12)


@pytest.mark.parametrize("interpolation", ["STEP", "LINEAR", "CUBICSPLINE"])
def test_evaluate_sampler_readonly_strided_empty(rng, interpolation):
    times = np.array([0.0, 1.0, 3.0])
    per = 3 if interpolation == "CUBICSPLINE" else 1
    wide = unit(rng, 2 * per * 3).reshape(per * 3, 8)
    values = wide[:, ::2]                       # non-contiguous
    for a in (times, wide):
        a.flags.writeable = False
    before = values.copy()
    t = np.array([0.5, 2.0])
    got = evaluate_sampler(times, values, interpolation, t, rotation=True)
    want = evaluate_sampler(times.copy(), np.ascontiguousarray(values), interpolation, t, rotation=True)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(values, before)
    assert evaluate_sampler(times, values, interpolation, np.empty(0), rotation=True).shape == (0, 4)


def test_single_key_sampler_holds_its_value(rng):
    v = unit(rng, 1)
    got = evaluate_sampler(np.array([0.5]), v, "LINEAR", np.array([0.0, 0.5, 9.0]), rotation=True)
    np.testing.assert_array_equal(got, np.repeat(v, 3, axis=0))


# --------------------------------------------------------------------------- identity, methods, encodings

@pytest.mark.parametrize("interpolation", ["STEP", "LINEAR", "CUBICSPLINE"])
def test_identity_resample_keeps_values(tmp_path, rng, interpolation):
    K = 31
    times = (np.arange(K) / 30).astype(np.float32)      # a 30 fps clip, as exporters write it
    per = 3 if interpolation == "CUBICSPLINE" else 1
    rot, vec = unit(rng, per * K), rng.normal(size=(per * K, 3))
    b = Builder()
    b.g.nodes = [pygltflib.Node(name="a")]
    anim = pygltflib.Animation()
    b.channel(anim, 0, "rotation", times, rot, "VEC4", interpolation)
    b.channel(anim, 0, "translation", times, vec, "VEC3", interpolation)
    b.g.animations = [anim]
    b.save(tmp_path / "in.glb")
    assert resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", fps=30) == (K, K)
    doc, data = load(tmp_path / "out.glb")
    for path, values in (("rotation", rot), ("translation", vec)):
        t, got, _ = channel_output(doc, data, 0, 0, path)
        np.testing.assert_array_equal(t, times)
        keys = np.asarray(values, np.float32).astype(np.float64).reshape(K, per, -1)[:, per // 2]
        if path == "rotation":
            keys /= np.linalg.norm(keys, axis=1, keepdims=True)
        assert_close(got, keys, path == "rotation", 2 * EPS32)


def test_step_and_cubic_samplers_are_written_linear(tmp_path, rng):
    # the issue: "a valid glTF/GLB with LINEAR samplers at the new rate", whatever the input's interpolation
    times = np.array([0.0, 0.5, 1.0], np.float32)
    steps = np.array([[0, 0, 0], [1, 0, 0], [3, 0, 0]], np.float32)
    rot = unit(rng, 3)
    cubic = rng.normal(size=(9, 3))
    b = Builder()
    b.g.nodes = [pygltflib.Node(name="a"), pygltflib.Node(name="b")]
    anim = pygltflib.Animation()
    b.channel(anim, 0, "translation", times, steps, "VEC3", "STEP")
    b.channel(anim, 0, "rotation", times, rot, "VEC4", "STEP")
    b.channel(anim, 1, "translation", times, cubic, "VEC3", "CUBICSPLINE")
    b.g.animations = [anim]
    b.save(tmp_path / "in.glb")
    resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", fps=4)
    doc, data = load(tmp_path / "out.glb")
    assert [s["interpolation"] for s in doc["animations"][0]["samplers"]] == ["LINEAR"] * 3
    t, got, _ = channel_output(doc, data, 0, 0, "translation")
    np.testing.assert_array_equal(t, [0, 0.25, 0.5, 0.75, 1])
    np.testing.assert_array_equal(got[:, 0], [0, 0, 1, 1, 3])       # the value each step holds at the new keys
    t, got, _ = channel_output(doc, data, 0, 0, "rotation")
    held = np.asarray(rot, np.float32).astype(np.float64)[[0, 0, 1, 1, 2]]
    assert_close(got, held / np.linalg.norm(held, axis=1, keepdims=True), True, 2 * EPS32)
    assert (np.sum(got[1:] * got[:-1], axis=1) >= 0).all()            # LINEAR keys: slerp takes the short path
    t, got, _ = channel_output(doc, data, 0, 1, "translation")
    c32 = np.asarray(cubic, np.float32).astype(np.float64)
    want = [spec_value(times, c32, "CUBICSPLINE", x, False) for x in t]
    np.testing.assert_allclose(got, want, rtol=0, atol=4 * EPS32 * np.abs(c32).max())
    assert doc["accessors"][doc["animations"][0]["samplers"][2]["output"]]["count"] == len(t)   # no tangents


def test_json_that_pygltflib_would_lose_is_kept(tmp_path, rng):
    # Why the writer keeps the document's JSON instead of saving through pygltflib's model: a load-and-save
    # with pygltflib 1.16.5 drops a node's default morph `weights` and rewrites `asset.generator`.  This
    # file is written as plain JSON (no pygltflib), with such properties and `extras` at several levels.
    pos = np.eye(3, dtype=np.float32)
    times = np.array([0.0, 0.5, 1.0], np.float32)
    rot = unit(rng, 3).astype(np.float32)
    parts = [pos, pos * 0.5, pos * -0.25, times, rot]            # mesh data first: its indices do not move
    blob = b"".join(p.tobytes() for p in parts)
    views, at = [], 0
    for p in parts:
        views.append({"buffer": 0, "byteOffset": at, "byteLength": p.nbytes})
        at += p.nbytes
    vec3 = {"componentType": F32, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]}
    doc_in = {
        "asset": {"version": "2.0", "generator": "hand-written JSON", "copyright": "none",
                  "extras": {"checked": True}},
        "extras": {"author": "tests", "list": [1, 2.5, None], "nested": {"a": {"b": []}}},
        "scene": 0, "scenes": [{"nodes": [0], "extras": {"layer": 2}}],
        "nodes": [{"name": "root", "children": [1], "extras": {"joint": "root"}},
                  {"name": "face", "mesh": 0, "weights": [0.25, 0.5], "extras": {"morphs": ["smile", "blink"]}}],
        "meshes": [{"name": "face", "weights": [0.0, 1.0], "primitives": [{
            "attributes": {"POSITION": 0}, "targets": [{"POSITION": 1}, {"POSITION": 2}],
            "extras": {"targetNames": ["smile", "blink"]}}]}],
        "accessors": [dict(vec3, bufferView=0),
                      dict(vec3, bufferView=1, min=[0, 0, 0], max=[0.5, 0.5, 0.5]),
                      dict(vec3, bufferView=2, min=[-0.25, -0.25, -0.25], max=[0, 0, 0]),
                      {"bufferView": 3, "componentType": F32, "count": 3, "type": "SCALAR", "min": [0.0],
                       "max": [1.0]},
                      {"bufferView": 4, "componentType": F32, "count": 3, "type": "VEC4"}],
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob), "extras": {"origin": "test"},
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "animations": [{"name": "turn", "extras": {"take": 1},
                        "samplers": [{"input": 3, "output": 4, "interpolation": "LINEAR", "extras": {"s": 0}}],
                        "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}]}],
    }
    (tmp_path / "in.gltf").write_text(json.dumps(doc_in))
    resample_gltf(tmp_path / "in.gltf", tmp_path / "out.gltf", fps=4)
    doc = json.loads((tmp_path / "out.gltf").read_text())
    for key in ("asset", "extras", "scene", "scenes", "nodes", "meshes"):
        assert doc[key] == doc_in[key], key
    assert doc["accessors"][:3] == doc_in["accessors"][:3]
    assert doc["buffers"][0]["extras"] == {"origin": "test"}
    anim = doc["animations"][0]
    assert without(anim, "samplers") == without(doc_in["animations"][0], "samplers")
    assert anim["samplers"][0]["extras"] == {"s": 0} and anim["samplers"][0]["interpolation"] == "LINEAR"
    _, data = load(tmp_path / "out.gltf")
    np.testing.assert_array_equal(decode(doc, data, anim["samplers"][0]["input"])[:, 0], np.arange(5) / 4)


@pytest.mark.parametrize("method", ["slerp", "squad", "bezier", "linear"])
def test_method_reinterpolates_rotation_keys_only(tmp_path, rng, method):
    b, animations = skinned(rng)
    b.save(tmp_path / "in.glb")
    res = run("resample", tmp_path / "in.glb", "-o", tmp_path / "out.glb", "--fps", 30, "--method", method)
    assert res.returncode == 0, res.stderr
    doc, data = load(tmp_path / "out.glb")
    for node, path, times, values, interp in animations[0]:
        t, got, kind = channel_output(doc, data, 0, node, path)
        v32 = np.asarray(values, np.float32).astype(np.float64)
        if path == "rotation" and interp != "STEP":
            keys = v32.reshape(len(times), -1, 4)[:, 1 if interp == "CUBICSPLINE" else 0]
            want = np.roll(np.asarray(Track(times, np.roll(keys, 1, axis=-1), method=method)(t)), -1, axis=-1)
        else:   # translation, scale, weights and STEP rotations keep their own interpolation
            want = [spec_value(times, v32.reshape(-1, got.shape[1]), interp, x, path == "rotation") for x in t]
        assert_close(got, want, path == "rotation", 16 * EPS32 * max(1.0, np.abs(v32).max()))
        assert kind == "LINEAR"


@pytest.mark.parametrize("ctype", [5120, 5122])
def test_normalized_integer_rotations(tmp_path, rng, ctype):
    scale = float(np.iinfo(DTYPES[ctype]).max)
    rot = unit(rng, 3)
    rot[1] = [0, 0, 0, -1]                    # -1 is stored as -scale (and -scale - 1 also decodes to -1)
    codes = np.round(rot * scale)
    codes[1, 3] = -scale - 1
    times = np.array([0.0, 0.5, 1.0], np.float32)
    b = Builder()
    b.g.nodes = [pygltflib.Node(name="a"), pygltflib.Node(name="m", mesh=0)]
    b.g.meshes = [pygltflib.Mesh(primitives=[pygltflib.Primitive(
        attributes=pygltflib.Attributes(POSITION=b.accessor(np.eye(3), "VEC3", bounds=True)),
        targets=[pygltflib.Attributes(POSITION=b.accessor(np.eye(3), "VEC3", bounds=True))] * 2)])]
    anim = pygltflib.Animation()
    b.channel(anim, 0, "rotation", times, codes, "VEC4", ctype=ctype, normalized=True)
    wcodes = rng.integers(0, 256 if ctype == 5120 else 65536, size=6)
    b.channel(anim, 1, "weights", times, wcodes, "SCALAR", ctype=5121 if ctype == 5120 else 5123, normalized=True)
    b.g.animations = [anim]
    b.save(tmp_path / "in.gltf", "embedded")
    gf = read_gltf(tmp_path / "in.gltf")
    decoded = np.maximum(codes / scale, -1.0)
    np.testing.assert_array_equal(read_accessor(gf, anim.samplers[0].output), decoded)
    np.testing.assert_array_equal(read_accessor(gf, anim.samplers[1].output)[:, 0],
                                  wcodes / (255.0 if ctype == 5120 else 65535.0))
    resample_gltf(tmp_path / "in.gltf", tmp_path / "out.gltf", fps=10)
    doc, data = load(tmp_path / "out.gltf")
    assert doc["buffers"][0]["uri"].startswith("data:application/octet-stream;base64,")
    t, got, _ = channel_output(doc, data, 0, 0, "rotation")
    unitkeys = decoded / np.linalg.norm(decoded, axis=1, keepdims=True)
    assert_close(got, [spec_value(times, unitkeys, "LINEAR", x, True) for x in t], True, 4 * EPS32)
    t, got, _ = channel_output(doc, data, 0, 1, "weights")
    w = (wcodes / (255.0 if ctype == 5120 else 65535.0)).reshape(3, 2)
    np.testing.assert_allclose(got, [spec_value(times, w, "LINEAR", x, False) for x in t], rtol=0, atol=2 * EPS32)


@pytest.mark.parametrize("ctype", [5121, 5123])
def test_unsigned_normalized_integer_rotations(tmp_path, rng, ctype):
    # unsigned bytes and shorts hold rotations whose components are all >= 0, decoded c / 255, c / 65535
    scale = float(np.iinfo(DTYPES[ctype]).max)
    codes = np.round(np.abs(unit(rng, 4)) * scale)
    times = np.array([0.0, 0.5, 1.0, 2.0], np.float32)
    b = Builder()
    b.g.nodes = [pygltflib.Node(name="a")]
    anim = pygltflib.Animation()
    b.channel(anim, 0, "rotation", times, codes, "VEC4", "LINEAR", ctype=ctype, normalized=True)
    b.g.animations = [anim]
    b.save(tmp_path / "in.glb")
    decoded = codes / scale
    np.testing.assert_array_equal(read_accessor(read_gltf(tmp_path / "in.glb"), anim.samplers[0].output), decoded)
    resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", fps=8)
    doc, data = load(tmp_path / "out.glb")
    t, got, _ = channel_output(doc, data, 0, 0, "rotation")
    assert len(t) == 17
    unitkeys = decoded / np.linalg.norm(decoded, axis=1, keepdims=True)
    assert_close(got, [spec_value(times, unitkeys, "LINEAR", x, True) for x in t], True, 4 * EPS32)


def test_sparse_output_accessor(tmp_path, rng):
    times = np.array([0.0, 1.0, 2.0], np.float32)
    base, patch = rng.normal(size=(3, 3)), rng.normal(size=(1, 3))
    b = Builder()
    b.g.nodes = [pygltflib.Node(name="a")]
    anim = pygltflib.Animation()
    b.channel(anim, 0, "translation", times, base, "VEC3")
    acc = b.g.accessors[anim.samplers[0].output]
    acc.sparse = pygltflib.Sparse(count=1, indices=pygltflib.AccessorSparseIndices(
        bufferView=b.view(np.array([2], np.uint16).tobytes()), componentType=5123),
        values=pygltflib.AccessorSparseValues(bufferView=b.view(patch.astype(np.float32).tobytes())))
    b.g.animations = [anim]
    b.save(tmp_path / "in.glb")
    want = np.asarray(base, np.float32).astype(np.float64)
    want[2] = np.float32(patch[0])
    np.testing.assert_array_equal(read_accessor(read_gltf(tmp_path / "in.glb"), 1), want)
    resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", fps=4)
    doc, data = load(tmp_path / "out.glb")
    t, got, _ = channel_output(doc, data, 0, 0, "translation")
    np.testing.assert_allclose(got, [spec_value(times, want, "LINEAR", x, False) for x in t], rtol=0,
                               atol=4 * EPS32 * np.abs(want).max())


# --------------------------------------------------------------------------- the rest of the file is kept

def without(doc, *keys):
    return {k: v for k, v in doc.items() if k not in keys}


@pytest.mark.parametrize("src_layout,dst_name", [("glb", "out.glb"), ("glb", "out.gltf"), ("embedded", "out.glb"),
                                                  ("embedded", "out.gltf"), ("external", "out.gltf"),
                                                  ("external", "sub/out.glb")])
def test_everything_else_is_kept(tmp_path, rng, src_layout, dst_name):
    b, _ = skinned(rng)
    src = tmp_path / ("in.glb" if src_layout == "glb" else "in.gltf")
    doc_in = b.save(src, src_layout)
    if src_layout != "glb":   # a property pygltflib cannot write: the default morph weights of a node
        doc_in["nodes"][4]["weights"] = [0.25, 0.5]
        doc_in["extras"] = {"author": "tests \u00e9\u4e2d", "empty": []}
        with open(src, "w") as f:
            json.dump(doc_in, f)
    dst = tmp_path / dst_name
    dst.parent.mkdir(exist_ok=True)
    resample_gltf(src, dst, fps=10)
    doc, data = load(dst)
    keep = ("accessors", "bufferViews", "buffers", "animations", "meshes", "skins")
    assert without(doc, *keep) == without(doc_in, *keep)
    assert without(doc["skins"][0], "inverseBindMatrices") == without(doc_in["skins"][0], "inverseBindMatrices")
    assert without(doc["meshes"][0], "primitives") == without(doc_in["meshes"][0], "primitives")
    for prim_in, prim in zip(doc_in["meshes"][0]["primitives"], doc["meshes"][0]["primitives"]):
        refs = ("attributes", "indices", "targets")
        assert without(prim, *refs) == without(prim_in, *refs)
        assert prim["attributes"] != prim_in["attributes"]      # renumbered: the old animation data went first
    gf_in = read_gltf(src)
    for prim_in, prim in zip(doc_in["meshes"][0]["primitives"], doc["meshes"][0]["primitives"]):
        refs = [(prim_in["attributes"][k], prim["attributes"][k]) for k in prim_in["attributes"]]
        refs += [(prim_in["indices"], prim["indices"])]
        refs += [(ti[k], to[k]) for ti, to in zip(prim_in["targets"], prim["targets"]) for k in ti]
        for old, new in refs:
            np.testing.assert_array_equal(decode(doc, data, new), read_accessor(gf_in, old))
            assert without(doc["accessors"][new], "bufferView") == without(doc_in["accessors"][old], "bufferView")
    ibm = doc["skins"][0]["inverseBindMatrices"]
    np.testing.assert_array_equal(decode(doc, data, ibm).reshape(3, 4, 4), np.tile(np.eye(4), (3, 1, 1)))
    for a_in, a in zip(doc_in["animations"], doc["animations"]):
        assert a["channels"] == a_in["channels"]
        assert without(a, "samplers") == without(a_in, "samplers")
    # compact: one buffer, the old animation data gone, every view used
    assert len(doc["buffers"]) == 1
    old_anim = {s[k] for a in doc_in["animations"] for s in a["samplers"] for k in ("input", "output")}
    assert len(doc["accessors"]) == len(doc_in["accessors"]) - len(old_anim) + 2 + 9
    used = {acc["bufferView"] for acc in doc["accessors"]}
    assert used == set(range(len(doc["bufferViews"])))
    assert doc["buffers"][0]["byteLength"] == sum(-(-v["byteLength"] // 4) * 4 for v in doc["bufferViews"])
    if dst_name.endswith(".gltf") and src_layout == "embedded":
        assert doc["buffers"][0]["uri"].startswith("data:application/octet-stream;base64,")
    elif dst_name.endswith(".gltf"):
        assert doc["buffers"][0]["uri"] == "out.bin" and (tmp_path / "out.bin").exists()
    else:
        assert "uri" not in doc["buffers"][0]


def test_nothing_written_on_error_and_input_untouched(tmp_path, rng):
    b, _ = skinned(rng)
    b.save(tmp_path / "in.glb")
    before = (tmp_path / "in.glb").read_bytes()
    with pytest.raises(ValueError):
        resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", times=[5.0, 6.0])
    assert sorted(os.listdir(tmp_path)) == ["in.glb"]
    resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", fps=7)
    assert (tmp_path / "in.glb").read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["in.glb", "out.glb"]


# --------------------------------------------------------------------------- the Khronos validator

def _validator():
    node = shutil.which("node")
    if node is None:
        pytest.skip("the Khronos glTF validator needs node (not installed)")
    npm = shutil.which("npm")
    root = subprocess.run([npm, "root", "-g"], capture_output=True, text=True).stdout.strip() if npm else ""
    if not os.path.isdir(os.path.join(root, "gltf-validator")):
        pytest.skip("the npm package gltf-validator is not installed (npm install -g gltf-validator)")
    return node, root


VALIDATE_JS = r"""
const fs = require('fs'), path = require('path'), validator = require('gltf-validator');
const file = process.argv[1];
validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
  uri: path.basename(file),
  externalResourceFunction: (uri) => new Promise((resolve, reject) => fs.readFile(
    path.join(path.dirname(file), decodeURIComponent(uri)),
    (err, data) => err ? reject(err.toString()) : resolve(new Uint8Array(data)))),
}).then((report) => console.log(JSON.stringify(report.issues)), (err) => { console.error(err); process.exit(3); });
"""


@pytest.mark.parametrize("name", ["out.glb", "out.gltf"])
def test_khronos_validator_finds_no_error(tmp_path, rng, name):
    node, root = _validator()
    b, _ = skinned(rng)
    b.save(tmp_path / "in.gltf", "external")
    resample_gltf(tmp_path / "in.gltf", tmp_path / name, fps=30, method="squad")
    env = dict(os.environ, NODE_PATH=root)
    reports = {}
    for f in ("in.gltf", name):
        res = subprocess.run([node, "-e", VALIDATE_JS, str(tmp_path / f)], capture_output=True, text=True,
                             env=env, timeout=120)
        assert res.returncode == 0, res.stderr
        reports[f] = json.loads(res.stdout)
    assert reports["in.gltf"]["numErrors"] == 0, reports["in.gltf"]["messages"]   # the test file itself is valid
    assert reports[name]["numErrors"] == 0, reports[name]["messages"]
    assert reports[name]["numWarnings"] == 0, reports[name]["messages"]


# --------------------------------------------------------------------------- the command line and malformed files

def test_cli_resample_and_conversions(tmp_path, rng):
    b, _ = skinned(rng)
    b.save(tmp_path / "in.glb")
    res = run("resample", tmp_path / "in.glb", "-o", tmp_path / "out.gltf", "--fps", 60)
    assert res.returncode == 0, res.stderr
    assert "7 keys" in res.stdout and "86 frames" in res.stdout     # 61 at 0..1 s, 25 at 0.1..0.5 s
    res = run("resample", tmp_path / "in.glb", "-o", tmp_path / "out.csv", "--fps", 60)
    assert res.returncode == 2 and "glTF files convert into .gltf, .glb only" in res.stderr
    res = run("resample", tmp_path / "in.glb", "-o", tmp_path / "huge.glb", "--fps", "1e12")
    assert res.returncode == 2 and "asks for" in res.stderr and "the limit is" in res.stderr
    assert res.stderr.count("\n") == 1 and not (tmp_path / "huge.glb").exists()
    res = run("resample", tmp_path / "in.glb", "-o", tmp_path / "in.glb", "--fps", 30)
    assert res.returncode == 2 and "--force" in res.stderr


def test_a_gltf_output_never_replaces_the_inputs_buffer(tmp_path, rng):
    # in.gltf keeps its buffer in in_data.bin; out "in_data.gltf" would write its own in_data.bin, which
    # --force used to let it replace: the input was left naming a buffer of other bytes
    b, _ = skinned(rng)
    b.save(tmp_path / "in.gltf", "external")
    buffer = tmp_path / "in_data.bin"
    before = buffer.read_bytes()
    dst = tmp_path / "in_data.gltf"
    for force in ([], ["--force"]):
        res = run("resample", tmp_path / "in.gltf", "-o", dst, "--fps", 60, *force)
        assert res.returncode == 2 and res.stderr == (
            f"quatarray: error: {dst}: would replace 'in_data.bin', the buffer file of the input 'in.gltf'; "
            "write the output under another name\n")
        assert buffer.read_bytes() == before and not dst.exists()
    with pytest.raises(cli.FormatError, match="would replace 'in_data.bin', the buffer file of the input"):
        resample_gltf(tmp_path / "in.gltf", dst, fps=60, force=True)
    assert buffer.read_bytes() == before
    # an output elsewhere, or embedded into a .glb, is fine
    assert run("resample", tmp_path / "in.gltf", "-o", tmp_path / "in.glb", "--fps", 60).returncode == 0
    assert sorted(os.listdir(tmp_path)) == ["in.glb", "in.gltf", "in_data.bin"]


def test_the_input_written_over_itself_rewrites_its_buffer_file(tmp_path):
    # scene.gltf keeps its buffer in scene.bin, the name its output's buffer takes: with --force the
    # two are rewritten together, and the file reads back
    keyframes_to_gltf(tmp_path / "arm.glb", read_csv(example_path("arm.csv")))
    src = tmp_path / "scene.gltf"
    resample_gltf(tmp_path / "arm.glb", src, fps=10)
    before = src.read_bytes(), (tmp_path / "scene.bin").read_bytes()
    res = run("resample", src, "-o", src, "--fps", 60)
    assert res.returncode == 2
    assert res.stderr == f"quatarray: error: {src}: is the input file; give --force to replace it\n"
    with pytest.raises(cli.FormatError, match="would replace 'scene.bin', the buffer file of the input 'scene.gltf'; "
                                               "give force=True to replace it"):
        resample_gltf(src, src, fps=60)
    assert (src.read_bytes(), (tmp_path / "scene.bin").read_bytes()) == before
    res = run("resample", src, "-o", src, "--fps", 60, "--force")
    assert res.returncode == 0, res.stderr
    doc, data = load(src)
    assert doc["buffers"][0]["uri"] == "scene.bin" and len(channel_output(doc, data, 0, 0, "rotation")[0]) == 241
    assert sorted(os.listdir(tmp_path)) == ["arm.glb", "scene.bin", "scene.gltf"]


@pytest.mark.parametrize("links", [True, False], ids=["hard links", "no hard links"])
@pytest.mark.parametrize("error", [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt()],
                         ids=["disk full", "interrupted"])
def test_a_gltf_and_its_buffer_file_are_replaced_together(tmp_path, monkeypatch, error, links):
    # the input written over itself: scene.bin is renamed into place, then scene.gltf; when that second
    # rename fails, scene.bin is put back (from a hard link, or a copy, to the old file) -- it used to stay
    # the new buffer under the old .gltf, which then read other bytes than it was written for
    keyframes_to_gltf(tmp_path / "arm.glb", read_csv(example_path("arm.csv")))
    src = tmp_path / "scene.gltf"
    resample_gltf(tmp_path / "arm.glb", src, fps=10)
    os.remove(tmp_path / "arm.glb")
    before = {name: (tmp_path / name).read_bytes() for name in os.listdir(tmp_path)}
    renamed, replace = [], os.replace

    def failing_second(a, b):
        renamed.append(os.path.basename(b))
        if len(renamed) == 2:
            raise error
        replace(a, b)

    def no_link(*args, **kwargs):
        raise PermissionError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(os, "replace", failing_second)
    if not links:
        monkeypatch.setattr(os, "link", no_link)
    with pytest.raises(type(error)) as info:
        resample_gltf(src, src, fps=60, force=True)
    assert renamed == ["scene.bin", "scene.gltf", "scene.bin"]     # the third puts the old scene.bin back
    if isinstance(error, OSError):
        assert info.value.filename == str(src)
    assert sorted(before) == ["scene.bin", "scene.gltf"]
    assert {name: (tmp_path / name).read_bytes() for name in os.listdir(tmp_path)} == before   # nothing left


@pytest.mark.parametrize("image, dst", [("scene.bin", "scene.gltf"), ("tex.bin", "tex.gltf")])
def test_an_image_of_the_input_is_never_replaced(tmp_path, rng, image, dst):
    # an image file named as the output's buffer file would be: refused with --force, also writing in place
    b, _ = skinned(rng)
    b.g.images = [pygltflib.Image(uri=image, mimeType="image/png")]
    b.save(tmp_path / "scene.gltf", "external")
    (tmp_path / image).write_bytes(b"a picture")
    res = run("resample", tmp_path / "scene.gltf", "-o", tmp_path / dst, "--fps", 60, "--force")
    assert res.returncode == 2 and res.stderr == (
        f"quatarray: error: {tmp_path / dst}: would replace {image!r}, an image of the input 'scene.gltf'; "
        "write the output under another name\n")
    assert (tmp_path / image).read_bytes() == b"a picture"
    assert sorted(os.listdir(tmp_path)) == sorted({"scene.gltf", "scene_data.bin", image})


def _malformed(tmp_path, rng, how):
    b, _ = skinned(rng)
    if how == "missing buffer":
        path = tmp_path / "in.gltf"
        b.save(path, "external")
        os.remove(tmp_path / "in_data.bin")
        return path, "buffer 0: cannot read 'in_data.bin'"
    path = tmp_path / "in.gltf"
    doc = b.save(path, "embedded")
    if how == "accessor out of range":
        doc["animations"][0]["samplers"][1]["output"] = 99
        match = "animation 0 ('walk') sampler 1 output: accessor 99 does not exist"
    elif how == "view out of buffer":
        doc["bufferViews"][3]["byteLength"] = 10 ** 6
        match = "bufferView 3: bytes"
    elif how == "accessor past its view":
        acc = doc["animations"][0]["samplers"][0]["output"]
        doc["accessors"][acc]["count"] = 1000
        match = f"accessor {acc}: 1000 elements of 12 bytes"
    elif how == "extension required":
        doc["extensionsUsed"] = doc["extensionsRequired"] = ["EXT_meshopt_compression"]
        match = "unsupported required extension 'EXT_meshopt_compression'"
    elif how == "glb without bin":
        path = tmp_path / "in.glb"
        text = json.dumps(without(doc, "buffers") | {"buffers": [{"byteLength": 8}]}).encode()
        text += b" " * (-len(text) % 4)
        path.write_bytes(struct.pack("<4sII", b"glTF", 2, 20 + len(text)) + struct.pack("<II", len(text), 0x4E4F534A)
                         + text)
        return path, "buffer 0 has no uri and the file has no GLB BIN chunk"
    elif how == "decreasing times":
        b2 = Builder()
        b2.g.nodes = [pygltflib.Node()]
        anim = pygltflib.Animation()
        b2.channel(anim, 0, "translation", [0.0, 0.5, 0.5], np.zeros((3, 3)), "VEC3")
        b2.g.animations = [anim]
        b2.save(path, "embedded")
        return path, "input times must be finite and strictly increasing, key 2 is 0.5"
    elif how == "not json":
        path.write_text("{not json")
        return path, "not a glTF file: bad JSON"
    with open(path, "w") as f:
        json.dump(doc, f)
    return path, match


@pytest.mark.parametrize("how", ["missing buffer", "accessor out of range", "view out of buffer",
                                 "accessor past its view", "extension required", "glb without bin",
                                 "decreasing times", "not json"])
def test_malformed_files_give_one_line_and_exit_2(tmp_path, rng, how):
    path, match = _malformed(tmp_path, rng, how)
    out = tmp_path / "out.glb"
    res = run("resample", path, "-o", out, "--fps", 30)
    assert res.returncode == 2
    assert res.stdout == ""
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("quatarray: error: ")
    assert match in res.stderr and str(path) in res.stderr
    assert not out.exists()


def test_no_animation_is_an_error(tmp_path):
    b = Builder()
    b.g.nodes = [pygltflib.Node(name="still")]
    b.accessor([[0.0, 0.0, 0.0]], "VEC3")
    b.save(tmp_path / "in.glb")
    assert cli.main(["resample", str(tmp_path / "in.glb"), "-o", str(tmp_path / "o.glb"), "--fps", "30"]) == 2


# --------------------------------------------------------------------------- the example file

def test_keyframes_to_gltf_round_trip(tmp_path):
    kf = read_csv(example_path("arm.csv"))
    keyframes_to_gltf(tmp_path / "arm.glb", kf)
    doc, data = load(tmp_path / "arm.glb")
    assert [n["name"] for n in doc["nodes"]] == list(kf.names)
    for j in range(len(kf.names)):
        t, got, kind = channel_output(doc, data, 0, j, "rotation")
        np.testing.assert_array_equal(t, kf.times.astype(np.float32))
        np.testing.assert_allclose(got, np.roll(kf.keys[:, j], -1, axis=-1), rtol=0, atol=EPS32)


def test_demo_writes_a_gltf_example(tmp_path):
    res = run("demo", "-o", tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "demo_arm.glb").exists()
    res = run("resample", tmp_path / "demo_arm.glb", "-o", tmp_path / "arm_30.glb", "--fps", 30, "--method", "squad")
    assert res.returncode == 0, res.stderr
    doc, data = load(tmp_path / "arm_30.glb")
    kf = read_csv(example_path("arm.csv"))
    t, got, _ = channel_output(doc, data, 0, 1, "rotation")
    want = Track(kf.times, kf.keys[:, 1], method="squad", extrapolate="clamp")(t)
    assert_close(got, np.roll(np.asarray(want), -1, axis=-1), True, 8 * EPS32)


def test_references_inside_images_and_extensions_are_renumbered(tmp_path, rng):
    # animation data first, so everything after it moves: an image in a buffer view, an instancing
    # attribute (EXT_mesh_gpu_instancing) and a Draco-compressed primitive's buffer view
    b = Builder()
    b.g.nodes = [pygltflib.Node(name="a"), pygltflib.Node(name="many", mesh=0)]
    anim = pygltflib.Animation()
    b.channel(anim, 0, "rotation", [0.0, 1.0], unit(rng, 2), "VEC4")
    png = bytes(range(7)) * 5
    draco = bytes(range(100, 123))
    b.g.images = [pygltflib.Image(bufferView=b.view(png), mimeType="image/png")]
    shifts = rng.normal(size=(3, 3))
    b.g.nodes[1].extensions = {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": b.accessor(shifts, "VEC3")}}}
    position = b.accessor(np.eye(3), "VEC3", bounds=True)
    b.g.meshes = [pygltflib.Mesh(primitives=[pygltflib.Primitive(
        attributes=pygltflib.Attributes(POSITION=position),
        extensions={"KHR_draco_mesh_compression": {"bufferView": b.view(draco), "attributes": {"POSITION": 0}}})])]
    b.g.extensionsUsed = ["EXT_mesh_gpu_instancing", "KHR_draco_mesh_compression"]
    b.g.extensionsRequired = ["KHR_draco_mesh_compression"]
    b.g.animations = [anim]
    b.save(tmp_path / "in.glb")
    resample_gltf(tmp_path / "in.glb", tmp_path / "out.glb", fps=5)
    doc, data = load(tmp_path / "out.glb")

    def view_bytes(j):
        v = doc["bufferViews"][j]
        return data[0][v["byteOffset"]:v["byteOffset"] + v["byteLength"]]

    assert view_bytes(doc["images"][0]["bufferView"]) == png
    prim = doc["meshes"][0]["primitives"][0]
    assert view_bytes(prim["extensions"]["KHR_draco_mesh_compression"]["bufferView"]) == draco
    assert prim["extensions"]["KHR_draco_mesh_compression"]["attributes"] == {"POSITION": 0}   # Draco ids, not accessors
    np.testing.assert_array_equal(decode(doc, data, prim["attributes"]["POSITION"]), np.eye(3))
    inst = doc["nodes"][1]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["TRANSLATION"]
    np.testing.assert_array_equal(decode(doc, data, inst), np.asarray(shifts, np.float32))
    assert inst != 3 and prim["attributes"]["POSITION"] != 4          # both moved down past the old animation data


def _with_extension(doc, name):
    """`doc` using extension `name`, with what it holds as the extension's spec has it."""
    view = len(doc["bufferViews"]) - 1
    if name == "EXT_structural_metadata":     # a property table's values are a buffer view
        doc["extensions"] = {name: {
            "schema": {"classes": {"part": {"properties": {"mass": {"type": "SCALAR", "componentType": "FLOAT32"}}}}},
            "propertyTables": [{"class": "part", "count": 1, "properties": {"mass": {"values": view}}}]}}
    elif name == "EXT_meshopt_compression":   # a buffer view's compressed bytes are in another buffer
        doc["bufferViews"][view]["extensions"] = {name: {
            "buffer": 0, "byteLength": 4, "byteStride": 4, "count": 1, "mode": "ATTRIBUTES"}}
    elif name == "KHR_materials_emissive_strength":
        doc["materials"] = [{"extensions": {name: {"emissiveStrength": 2.0}}}]
    elif name == "MSFT_texture_dds":
        doc["images"] = [{"uri": "t.dds"}]
        doc["textures"] = [{"extensions": {name: {"source": 0}}}]
    doc["extensionsUsed"] = [name]
    return doc


@pytest.mark.parametrize("name", ["EXT_structural_metadata", "EXT_meshopt_compression", "CESIUM_primitive_outline"])
def test_an_extension_that_may_hold_moved_indices_is_refused(tmp_path, rng, capsys, name):
    # writing renumbers accessors and buffer views: an extension whose indices into them the writer does
    # not renumber would be left pointing at other data, as these were (used, not required)
    b, _ = skinned(rng)
    src = tmp_path / "in.gltf"
    doc = _with_extension(b.save(src, "embedded"), name)
    src.write_text(json.dumps(doc))
    message = (f"{src}: extensionsUsed lists {name!r}: it may hold indices of accessors, buffer views or buffers, "
               "which writing the file back renumbers (supported: EXT_mesh_gpu_instancing, ")
    assert cli.main(["resample", str(src), "-o", str(tmp_path / "out.glb"), "--fps", "10"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"quatarray: error: {message}") and err.endswith(", KHR_materials_*)\n")
    with pytest.raises(cli.FormatError, match=re.escape(message)):
        reduce_file(src, tmp_path / "out.gltf", "1deg")
    assert os.listdir(tmp_path) == ["in.gltf"]


@pytest.mark.parametrize("name", ["KHR_materials_emissive_strength", "MSFT_texture_dds", "KHR_animation_pointer"])
def test_an_extension_without_such_indices_is_written_back(tmp_path, rng, name):
    # used and required: one list says what is read right and written back intact
    b, _ = skinned(rng)
    src = tmp_path / "in.gltf"
    doc_in = _with_extension(b.save(src, "embedded"), name)
    doc_in["extensionsRequired"] = [name]
    src.write_text(json.dumps(doc_in))
    resample_gltf(src, tmp_path / "out.gltf", fps=10)
    doc, _ = load(tmp_path / "out.gltf")
    keep = ("accessors", "bufferViews", "buffers", "animations", "meshes", "skins")
    assert without(doc, *keep) == without(doc_in, *keep) and doc["extensionsRequired"] == [name]


def test_cli_times_file_and_message(tmp_path, rng):
    b, animations = skinned(rng)
    b.save(tmp_path / "in.glb")
    (tmp_path / "t.txt").write_text("0.1\n0.2\n0.4\n")
    res = run("resample", tmp_path / "in.glb", "-o", tmp_path / "out.glb", "--times", tmp_path / "t.txt")
    assert res.returncode == 0, res.stderr
    assert "6 frames (each sampler's own interpolation," in res.stdout                       # 3 times in each of the two animations
    doc, data = load(tmp_path / "out.glb")
    t, got, _ = channel_output(doc, data, 0, 1, "translation")
    np.testing.assert_array_equal(t, np.float32([0.1, 0.2, 0.4]))
    res = run("resample", tmp_path / "in.glb", "-o", tmp_path / "out2.glb", "--times", tmp_path / "t.txt",
              "--method", "squad")
    assert res.returncode == 0, res.stderr
    (tmp_path / "t.txt").write_text("0.05\n0.2\n")
    res = run("resample", tmp_path / "in.glb", "-o", tmp_path / "out3.glb", "--times", tmp_path / "t.txt")
    assert res.returncode == 2 and "query time 0.05 is outside animation 1's key times" in res.stderr
    assert "--extrapolate clamp" in res.stderr and not (tmp_path / "out3.glb").exists()


@pytest.mark.parametrize("name", ["out.gltf", "out.glb"])
def test_text_that_utf8_cannot_hold_stays_escaped(tmp_path, rng, name):
    b, _ = skinned(rng)
    doc = b.save(tmp_path / "in.gltf", "embedded")
    doc["nodes"][0]["name"] = "\ud800 lone"           # valid JSON (an escape), not encodable as UTF-8
    with open(tmp_path / "in.gltf", "w") as f:
        json.dump(doc, f)
    resample_gltf(tmp_path / "in.gltf", tmp_path / name, fps=10)
    assert read_gltf(tmp_path / name).json["nodes"][0]["name"] == "\ud800 lone"


@pytest.mark.parametrize("where,value,match", [
    (["animations"], "x", "animations: expected an array of objects"),
    (["animations", 0, "channels", 0, "target"], 3, "animations[0].channels[0].target: expected an object"),
    (["accessors", 0, "componentType"], [], "accessor 0: unknown componentType []"),
    (["accessors", 0, "count"], True, "accessor 0: expected count >= 1, got True"),
    (["meshes", 0, "primitives", 0, "attributes"], None, "meshes[0].primitives[0].attributes: expected an object"),
    (["meshes", 0, "primitives", 0, "attributes", "POSITION"], [1], "a reference to accessor [1]"),
    (["nodes", 4, "extensions"], [], "nodes[4].extensions: expected an object"),
    (["extensionsRequired"], "KHR_texture_transform", "extensionsRequired: expected an array of strings"),
    (["extensionsUsed"], {"KHR_texture_transform": 1}, "extensionsUsed: expected an array of strings"),
])
def test_wrong_json_shapes_are_format_errors(tmp_path, rng, capsys, where, value, match):
    b, _ = skinned(rng)
    doc = b.save(tmp_path / "in.gltf", "embedded")
    container = doc
    for key in where[:-1]:
        container = container[key]
    container[where[-1]] = value
    with open(tmp_path / "in.gltf", "w") as f:
        json.dump(doc, f)
    assert cli.main(["resample", str(tmp_path / "in.gltf"), "-o", str(tmp_path / "out.glb"), "--fps", "10"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and match in err
    assert not (tmp_path / "out.glb").exists()


def _tweaked(tmp_path, change):
    """The arm example as an embedded .gltf, its JSON changed by `change(doc)`."""
    import json
    src = tmp_path / "arm.gltf"
    keyframes_to_gltf(src, read_csv(example_path("arm.csv")))
    doc = json.loads(src.read_text())
    change(doc)
    out = tmp_path / "tweaked.gltf"
    out.write_text(json.dumps(doc))
    return out


def _rotation_output(doc):
    return doc["accessors"][doc["animations"][0]["samplers"][0]["output"]]


def _nest(doc, depth):
    inner = {}
    doc["extras"] = inner
    for _ in range(depth):
        inner["x"] = {}
        inner = inner["x"]


@pytest.mark.parametrize("case, change, message", [
    ("byteStride 2.5", lambda d: d["bufferViews"][_rotation_output(d)["bufferView"]].update(byteStride=2.5),
     "has byteStride 2.5; expected an integer multiple of 4 from 4 to 252, at least the 16 bytes of an element"),
    ("byteStride 3", lambda d: d["bufferViews"][_rotation_output(d)["bufferView"]].update(byteStride=3),
     "has byteStride 3; expected an integer multiple of 4"),
    ("byteStride 8", lambda d: d["bufferViews"][_rotation_output(d)["bufferView"]].update(byteStride=8),
     "at least the 16 bytes of an element"),
    ("node 99", lambda d: d["animations"][0]["channels"][0]["target"].update(node=99),
     "channel 0: target node 99 does not exist (the file has 3 nodes)"),
    ("UNSIGNED_INT", lambda d: _rotation_output(d).update(componentType=5125),
     "rotation output of componentType UNSIGNED_INT; expected FLOAT or a normalized BYTE"),
    ("SHORT not normalized", lambda d: _rotation_output(d).update(componentType=5122),
     "rotation output of componentType SHORT (not normalized)"),
    ("extras 900 deep", lambda d: _nest(d, 900), "JSON nested more than 128 levels deep"),
])
def test_malformed_gltf_is_a_one_line_error(tmp_path, case, change, message):
    src = _tweaked(tmp_path, change)
    res = run("resample", src, "-o", tmp_path / "out.glb", "--fps", 10)
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    assert res.stderr.startswith(f"quatarray: error: {src}") and message in res.stderr, res.stderr
    assert not (tmp_path / "out.glb").exists()


def test_json_nested_past_the_parsers_recursion_is_a_one_line_error(tmp_path):
    src = tmp_path / "deep.gltf"
    src.write_text('{"asset": {"version": "2.0"}, "extras": ' + "[" * 100_000 + "]" * 100_000 + "}")
    res = run("resample", src, "-o", tmp_path / "out.glb", "--fps", 10)
    assert res.returncode == 2 and res.stderr == f"quatarray: error: {src}: JSON nested more than 128 levels deep\n"


def test_extras_nested_within_the_limit_are_written_back(tmp_path):
    import json
    src = _tweaked(tmp_path, lambda d: _nest(d, 120))
    res = run("resample", src, "-o", tmp_path / "out.gltf", "--fps", 10)
    assert res.returncode == 0, res.stderr
    assert json.loads((tmp_path / "out.gltf").read_text())["extras"] == json.loads(src.read_text())["extras"]
