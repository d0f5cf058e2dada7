"""glTF 2.0 files (``.gltf``, ``.glb``): resample the animations and write the file back.

The document is kept as the JSON object it was read as, and only what
resampling changes is changed: the animation samplers (their ``input``,
``output`` and ``interpolation``), the accessors and buffer views that held
the old animation data, and the buffers, which are rewritten as one compact
buffer.  Every other object and property -- nodes, meshes, skins, materials,
images, ``extras``, extensions -- is written back as it was, with accessor and
buffer-view indices renumbered where the compaction moved them (core
properties, ``KHR_draco_mesh_compression`` and ``EXT_mesh_gpu_instancing``).
A file using another extension that may hold such indices (say
``EXT_structural_metadata``, ``EXT_meshopt_compression``) is refused: its
data would be left pointing at what moved.
The file is read and written as JSON here, not through pygltflib's object
model (the issue asked for pygltflib): a load-and-save with pygltflib 1.16.5
drops core properties -- a node's default morph ``weights``, a mesh's empty
``primitives`` array -- and rewrites ``asset.generator``, so the file would
not come back untouched.  pygltflib stays the tool the tests build their
input files with.

Reading lives in `quatarray.formats.gltf_read`, the samplers' maths in
`quatarray.formats.gltf_sampler`.  A ``.glb`` output holds its buffer in the ``BIN``
chunk; a ``.gltf`` output embeds it as a data URI when the input did, and
otherwise writes ``<name>.bin`` beside it.  Files are written atomically.
Every problem with a file raises `FormatError` naming the file and the object.
"""

import base64
import copy
import errno
import json
import os
import struct
import urllib.parse

import numpy as np

from .atomic import atomic_files
from .gltf_read import (BIN_CHUNK, FLOAT, GLB_MAGIC, JSON_CHUNK, SIZES, check_extensions, read_animations,
                        read_gltf)
from .gltf_sampler import resample_sampler
from .keyframes import fps_times
from .text import FormatError, check_size, option, same_file

__all__ = ["write_gltf", "resample_gltf", "keyframes_to_gltf"]

_ALIGN = 4   # every buffer view starts at a multiple of the largest component size


# --------------------------------------------------------------------------- writing

def _accessor_slots(doc):
    """(container, key) of every accessor reference outside the animations."""
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            attributes = prim.get("attributes", {})
            yield from ((attributes, k) for k in attributes)
            if "indices" in prim:
                yield prim, "indices"
            for target in prim.get("targets", []):
                yield from ((target, k) for k in target)
    for skin in doc.get("skins", []):
        if "inverseBindMatrices" in skin:
            yield skin, "inverseBindMatrices"
    for node in doc.get("nodes", []):
        attributes = (node.get("extensions", {}).get("EXT_mesh_gpu_instancing") or {}).get("attributes", {})
        yield from ((attributes, k) for k in attributes)


def _view_slots(doc, accessors):
    """(container, key) of every buffer-view reference, in `accessors` and elsewhere."""
    for acc in accessors:
        if "bufferView" in acc:
            yield acc, "bufferView"
        sparse = acc.get("sparse") or {}
        for part in ("indices", "values"):
            if "bufferView" in (sparse.get(part) or {}):
                yield sparse[part], "bufferView"
    for image in doc.get("images", []):
        if "bufferView" in image:
            yield image, "bufferView"
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            draco = prim.get("extensions", {}).get("KHR_draco_mesh_compression")
            if draco and "bufferView" in draco:
                yield draco, "bufferView"


def _targets(slots):
    """The indices the slots hold (what is not an index is caught by `_renumber`)."""
    return {c[k] for c, k in slots if type(c[k]) is int}


def _renumber(slots, mapping, what, path):
    for container, key in slots:
        old = container[key]
        if not (type(old) is int and old in mapping):
            raise FormatError(f"a reference to {what} {old!r}, which does not exist", path)
        container[key] = mapping[old]


class _Blob:
    """The new buffer: aligned buffer views appended one after the other."""

    def __init__(self):
        self.data = bytearray()
        self.views = []

    def add(self, data, view=None):
        self.data += b"\0" * (-len(self.data) % _ALIGN)
        view = dict(view or {})
        view.update(buffer=0, byteOffset=len(self.data), byteLength=len(data))
        self.data += data
        self.views.append(view)
        return len(self.views) - 1


def _float_accessor(blob, accessors, values, kind, name=None, bounds=False):
    """Append tightly packed float32 `values` (count, n) and an accessor for them; return its index."""
    values = np.ascontiguousarray(values, dtype="<f4")
    acc = {"bufferView": blob.add(values.tobytes()), "componentType": FLOAT, "count": len(values), "type": kind}
    if bounds:
        acc["min"], acc["max"] = values.min(axis=0).tolist(), values.max(axis=0).tolist()
    if name is not None:
        acc["name"] = name
    accessors.append(acc)
    return len(accessors) - 1


def write_gltf(dst, gf, animations):
    """Write `gf` to `dst` (``.glb`` or ``.gltf``) with the animations' samplers replaced by LINEAR ones.

    Parameters
    ----------
    dst : str or os.PathLike
    gf : GltfFile
        Not modified.
    animations : list
        One entry per animation of the file: ``(times, outputs)`` with
        ``times`` (M,) float32 shared by all its samplers and ``outputs`` a
        list of values (M, n), one per sampler, the keys of a LINEAR
        sampler; a dict ``{sampler index: (times, values)}`` to replace only
        those samplers, each by a LINEAR one with its own key times; or None
        to leave that animation's samplers as they are.

    Accessors and buffer views that only the replaced samplers used are
    dropped; everything else is copied into one compact buffer.  A file
    using an extension not in `quatarray.formats.gltf_read.SUPPORTED_EXTENSIONS`
    is a `FormatError`.
    """
    dst = os.fspath(dst)
    _check_extensions(gf)
    doc = copy.deepcopy(gf.json)
    old_accessors = doc.get("accessors", [])
    def swapped(i, new):   # whether sampler i of an animation is replaced
        return new is not None and (not isinstance(new, dict) or i in new)

    slots = [(s, k, swapped(i, new)) for anim, new in zip(doc.get("animations", []), animations)
             for i, s in enumerate(anim.get("samplers", [])) for k in ("input", "output") if k in s]
    replaced = {s[k] for s, k, out in slots if out}
    kept_anim = {s[k] for s, k, out in slots if not out}
    used = _targets(_accessor_slots(doc)) | kept_anim
    keep = [i for i in range(len(old_accessors)) if i not in replaced or i in used]
    accessor_map = {old: new for new, old in enumerate(keep)}
    accessors = [old_accessors[i] for i in keep]
    dropped = [old_accessors[i] for i in range(len(old_accessors)) if i not in accessor_map]
    views = doc.get("bufferViews", [])
    dead = _targets(_view_slots({}, dropped)) - _targets(_view_slots(doc, accessors))
    view_map, blob = {}, _Blob()
    for j, view in enumerate(views):
        if j not in dead:
            start = view.get("byteOffset", 0)
            view_map[j] = blob.add(gf.buffers[view["buffer"]][start:start + view["byteLength"]], view)
    _renumber(_accessor_slots(doc), accessor_map, "accessor", gf.path)
    _renumber(_view_slots(doc, accessors), view_map, "bufferView", gf.path)
    for anim, new in zip(doc.get("animations", []), animations):
        samplers = anim.get("samplers", [])
        if new is None or isinstance(new, dict):
            _renumber([(s, k) for i, s in enumerate(samplers) if not swapped(i, new)
                       for k in ("input", "output") if k in s], accessor_map, "accessor", gf.path)
            for i, (times, values) in (new or {}).items():
                sampler, old = samplers[i], old_accessors[samplers[i]["output"]]
                name = old_accessors[sampler["input"]].get("name")
                sampler.update(
                    input=_float_accessor(blob, accessors, np.reshape(times, (-1, 1)), "SCALAR", name, bounds=True),
                    interpolation="LINEAR",
                    output=_float_accessor(blob, accessors, np.reshape(values, (-1, SIZES[old["type"]])),
                                           old["type"], old.get("name")))
            continue
        times, outputs = new
        name = old_accessors[samplers[0]["input"]].get("name") if samplers else None
        shared = _float_accessor(blob, accessors, np.reshape(times, (-1, 1)), "SCALAR", name, bounds=True)
        for sampler, values in zip(samplers, outputs):
            old = old_accessors[sampler["output"]]
            n = SIZES[old["type"]]
            sampler.update(input=shared, interpolation="LINEAR",
                           output=_float_accessor(blob, accessors, np.reshape(values, (-1, n)), old["type"],
                                                  old.get("name")))
    blob.data += b"\0" * (-len(blob.data) % _ALIGN)
    doc["bufferViews"], doc["accessors"] = blob.views, accessors
    for key in ("bufferViews", "accessors"):
        if not doc[key]:
            del doc[key]
    buffer = {k: v for k, v in (doc.get("buffers") or [{}])[0].items() if k not in ("uri", "byteLength")}
    buffer["byteLength"] = len(blob.data)
    doc["buffers"] = [buffer] if blob.data else []
    if not doc["buffers"]:
        del doc["buffers"]
    _write_document(dst, doc, bytes(blob.data), gf.layout)


def _json_bytes(doc, **style):
    """UTF-8 JSON; names stay readable, but a lone surrogate escape (valid JSON) stays escaped."""
    try:
        return json.dumps(doc, ensure_ascii=False, **style).encode("utf-8")
    except UnicodeEncodeError:
        return json.dumps(doc, **style).encode("ascii")


def _sidecar(dst):
    """The ``.bin`` file a ``.gltf`` output at `dst` keeps its buffer in (unless embedded)."""
    return os.path.join(os.path.dirname(dst), os.path.splitext(os.path.basename(dst))[0] + ".bin")


def _input_files(gf):
    """(what, path) of the files a glTF input is made of: itself, and the files its buffers and images name."""
    folder = os.path.dirname(os.path.abspath(gf.path))
    yield "the input", gf.path
    for key, what in (("buffers", "the buffer file"), ("images", "an image")):
        for item in gf.json.get(key, []):
            uri = item.get("uri")
            if isinstance(uri, str) and not uri.startswith("data:") and len(urllib.parse.urlsplit(uri).scheme) <= 1:
                yield what, os.path.join(folder, urllib.parse.unquote(uri))


def _check_extensions(gf):
    check_extensions(gf.json.get("extensionsUsed", []), "extensionsUsed lists", gf.path,
                     ": it may hold indices of accessors, buffer views or buffers, which writing the file back "
                     "renumbers")


def check_writable(gf, dst, force):
    """Refuse, before anything is computed or written, what `write_gltf` may not write: a file using an
    extension it cannot write back, or a ``.bin`` beside the output `dst` that would replace a file it
    may not.

    A file of the input `gf` never: the input would lose its buffer or an
    image.  The one exception is writing the input over itself with `force`,
    where its buffer file is rewritten together with it.  Any other existing
    file only with `force`.  Every command that writes a glTF file it read as
    `gf` (resample, reduce) calls it; `dst` itself follows
    `quatarray.formats.resample_file`'s rule.
    """
    _check_extensions(gf)
    dst = os.fspath(dst)
    if os.path.splitext(dst)[1].lower() != ".gltf" or gf.layout == "embedded":
        return   # no .bin: a .glb holds its buffer, and an embedded input stays embedded
    sidecar = _sidecar(dst)
    clashes = {what for what, file in _input_files(gf) if same_file(sidecar, file)}
    in_place = clashes == {"the buffer file"} and same_file(dst, gf.path)
    if clashes and not (in_place and force):
        what = " and ".join(sorted(clashes))
        fix = f"give {option('force')} to replace it" if in_place else "write the output under another name"
        raise FormatError(f"would replace {os.path.basename(sidecar)!r}, {what} of the input "
                          f"{os.path.basename(gf.path)!r}; {fix}", dst)
    if os.path.lexists(sidecar) and not force:
        raise FileExistsError(errno.EEXIST, f"exists (the buffer file of the output {os.path.basename(dst)!r}); "
                              f"give {option('force')} to replace it", sidecar)


def _write_document(dst, doc, data, layout):
    """Write the document and its one buffer `data`: GLB, or .gltf with a data URI or a .bin beside it
    (the .bin and the .gltf replaced together: if either fails, both are left as they were)."""
    if os.path.splitext(dst)[1].lower() == ".glb":
        text = _json_bytes(doc, separators=(",", ":"))
        text += b" " * (-len(text) % 4)
        chunks = struct.pack("<II", len(text), JSON_CHUNK) + text
        if data:
            chunks += struct.pack("<II", len(data), BIN_CHUNK) + data
        files = {dst: struct.pack("<4sII", GLB_MAGIC, 2, 12 + len(chunks)) + chunks}
    else:
        files = {}
        if data and layout == "embedded":
            doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode("ascii")
        elif data:
            doc["buffers"][0]["uri"] = urllib.parse.quote(os.path.basename(_sidecar(dst)))
            files[_sidecar(dst)] = data
        files[dst] = _json_bytes(doc, indent=2) + b"\n"
    with atomic_files() as staged:
        for path, content in files.items():
            with staged.open(path, binary=True) as f:
                f.write(content)


# --------------------------------------------------------------------------- resampling

def resample_gltf(src, dst, *, fps=None, times=None, method=None, extrapolate="raise", force=False):
    """Resample every animation of a glTF file and write it to `dst` (``.gltf`` or ``.glb``).

    Each animation is sampled on one time grid shared by its samplers:
    ``t0 + k / fps`` from its first to its last key time (over all its
    samplers; a sampler whose keys end earlier holds its end values there,
    as the spec says), or at `times`.  Every sampler is written LINEAR, with
    keys at those times holding the values its own interpolation gives there
    (a STEP sampler's held value, a CUBICSPLINE sampler's curve).  Between
    the new keys a step thus becomes a ramp one frame long: sample at the
    rate the steps need.

    Parameters
    ----------
    src, dst : str or os.PathLike
    fps : float, optional
    times : array_like, optional
        Strictly increasing query times (seconds); give `fps` or `times`.
    method : {None, 'slerp', 'squad', 'bezier', 'linear'}
        None keeps each sampler's own interpolation; a method re-interpolates
        the keys of LINEAR and CUBICSPLINE rotation samplers with that
        `quatarray.interpolate.Track` curve.
    extrapolate : {'raise', 'clamp', 'extend'}
        `times` outside an animation's keys: 'raise' a ValueError, or 'clamp'
        to its end values, as glTF players do; 'extend' is refused there
        (glTF defines no extrapolation).
    force : bool, default False
        Allow the ``.bin`` file a ``.gltf`` output writes beside it to
        replace an existing file; without it, an existing one is a
        `FileExistsError`, before anything is written.  A file of the input
        (its buffer, an image) is a `FormatError` even with `force`, except
        the input's buffer file when `dst` is the input itself.  `dst` itself
        is replaced (`quatarray.formats.resample_file` refuses an existing
        `dst` without `force`).

    Returns
    -------
    tuple of int
        ``(key times read, frames written)``, summed over the animations.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray.formats import example_path, read_csv
    >>> from quatarray.formats import keyframes_to_gltf, resample_gltf
    >>> tmp = tempfile.TemporaryDirectory()
    >>> src, dst = os.path.join(tmp.name, "arm.glb"), os.path.join(tmp.name, "arm_60.glb")
    >>> keyframes_to_gltf(src, read_csv(example_path("arm.csv")))
    >>> resample_gltf(src, dst, fps=60)
    (11, 241)
    """
    gf = read_gltf(src)
    check_writable(gf, dst, force)
    animations = read_animations(gf)
    if not any(animations):
        raise FormatError("no animation samplers to resample", gf.path)
    if times is not None:
        times = np.asarray(times, np.float64)
        if times.ndim != 1 or not len(times) or not np.isfinite(times).all() or (np.diff(times) <= 0).any():
            raise ValueError("expected times to be finite and strictly increasing")
    new, nkeys, nframes = [], 0, 0
    for a, samplers in enumerate(animations):
        if not samplers:
            new.append(None)
            continue
        t0, t1 = min(s.times[0] for s in samplers), max(s.times[-1] for s in samplers)
        per_frame = 1 + sum(s.values.shape[1] for s in samplers)   # a time and every sampler's values
        if times is None:
            t = _fps_grid(t0, t1, fps, per_frame)
        else:
            check_size(len(times), per_frame, "the query times")
            t = times
        grid = t.astype(np.float32)   # key times are float32: 0.1 s is the key stored as 0.1
        if (np.diff(grid) <= 0).any():
            raise ValueError(f"times closer than float32 key times can hold near {float(t[-1])!r} s")
        if extrapolate != "clamp" and (grid[0] < t0 or grid[-1] > t1):
            bad = t[0] if grid[0] < t0 else t[-1]
            raise ValueError(f"query time {float(bad)!r} is outside animation {a}'s key times [{float(t0)!r}, "
                             f"{float(t1)!r}] and extrapolate is {extrapolate!r} (glTF holds the end values: "
                             f"use {option('extrapolate', 'clamp')})")
        t = grid.astype(np.float64)   # the values belong to the times as written
        outputs = [resample_sampler(s.times, s.values, s.interpolation, t, s.path == "rotation", method)
                   for s in samplers]
        new.append((grid, outputs))
        nkeys += len(np.unique(np.concatenate([s.times for s in samplers])))
        nframes += len(t)
    write_gltf(dst, gf, new)
    return nkeys, nframes


def _fps_grid(t0, t1, fps, per_frame):
    """`fps_times` from t0 to t1, where t1 counts as reached within float32 rounding.

    Key times are float32 in glTF: a last key at k / fps is stored a little
    below it as often as not, and the grid must still include it.
    """
    slack = 4 * float(np.spacing(np.float32(max(abs(t0), abs(t1)))))
    return np.minimum(fps_times(t0, t1 + slack, fps, per_frame), t1)


# --------------------------------------------------------------------------- an example file

def keyframes_to_gltf(path, keyframes, *, offset=(0.0, 0.3, 0.0)):
    """Write quaternion keyframes as a glTF animation of a chain of nodes (one per track).

    Track j becomes node j, a child of node j - 1, translated by `offset`;
    its keys become a LINEAR rotation sampler (scalar-last, as glTF stores
    them).  ``.glb`` or ``.gltf`` (buffer embedded), written atomically.
    Used by ``quatarray demo`` to make an example file.
    """
    keys = np.asarray(keyframes.keys, np.float64)
    keys = keys.reshape(len(keys), -1, 4)
    names = keyframes.names or tuple(f"q{j}" for j in range(keys.shape[1]))
    blob, accessors = _Blob(), []
    shared = _float_accessor(blob, accessors, np.reshape(keyframes.times, (-1, 1)), "SCALAR", "times", bounds=True)
    nodes, samplers, channels = [], [], []
    for j, name in enumerate(names):
        nodes.append({"name": name, "translation": list(offset) if j else [0.0, 0.0, 0.0]})
        if j + 1 < len(names):
            nodes[-1]["children"] = [j + 1]
        out = _float_accessor(blob, accessors, np.roll(keys[:, j], -1, axis=-1), "VEC4", f"{name} rotation")
        samplers.append({"input": shared, "output": out, "interpolation": "LINEAR"})
        channels.append({"sampler": j, "target": {"node": j, "path": "rotation"}})
    doc = {"asset": {"version": "2.0", "generator": "quatarray"}, "scene": 0,
           "scenes": [{"nodes": [0]}], "nodes": nodes,
           "animations": [{"name": "keyframes", "samplers": samplers, "channels": channels}],
           "accessors": accessors, "bufferViews": blob.views, "buffers": [{"byteLength": len(blob.data)}]}
    _write_document(os.fspath(path), doc, bytes(blob.data), "embedded")
