"""glTF 2.0 files (``.gltf``, ``.glb``): the container, buffers, accessors and animations, read.

The document is kept as the JSON object it was read as (`GltfFile.json`),
with the bytes of its buffers beside it; `quatarray.formats.gltf` writes it back.
Buffers are read from a GLB ``BIN`` chunk, a base64 ``data:`` URI or a file
beside the ``.gltf``.  Accessors are decoded to float64 as the spec says
(normalized integers, sparse accessors, byte strides); the animations'
samplers to `Sampler` tables.  Every problem with a file raises
`FormatError` naming the file and the object (one line).
"""

import base64
import binascii
import dataclasses
import json
import os
import struct
import urllib.parse

import numpy as np

from .gltf_sampler import INTERPOLATIONS
from .text import FormatError

__all__ = ["SUPPORTED_EXTENSIONS", "GltfFile", "Sampler", "read_gltf", "read_accessor", "read_animations"]

GLB_MAGIC = b"glTF"
JSON_CHUNK, BIN_CHUNK = 0x4E4F534A, 0x004E4942
FLOAT = 5126
_COMPONENTS = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", FLOAT: "<f4"}
_INDEX_COMPONENTS = (5121, 5123, 5125)
_NORMALISED = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}   # max(c / d, -1)
SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}   # matrices never hold animation data
_NAMES = {5120: "BYTE", 5121: "UNSIGNED_BYTE", 5122: "SHORT", 5123: "UNSIGNED_SHORT", 5125: "UNSIGNED_INT",
          FLOAT: "FLOAT"}
#: Nesting of the JSON document read (objects and arrays); deeper ones are refused before copying.
MAX_DEPTH = 128
_PATH_TYPES = {"rotation": "VEC4", "translation": "VEC3", "scale": "VEC3", "weights": "SCALAR"}

#: Extensions a file may use or require.  None of them changes how animation data is read, and none
#: holds an index into accessors, buffer views or buffers, which writing the file back renumbers --
#: except KHR_draco_mesh_compression and EXT_mesh_gpu_instancing, whose indices the writer renumbers
#: too.  The indices they hold otherwise (images, textures, materials, nodes) never move.  With them,
#: every ``KHR_materials_*`` extension (materials hold texture indices only).
SUPPORTED_EXTENSIONS = frozenset({
    "KHR_mesh_quantization", "KHR_texture_transform", "KHR_texture_basisu", "KHR_lights_punctual",
    "KHR_materials_variants", "KHR_xmp_json_ld", "KHR_animation_pointer", "KHR_node_visibility",
    "KHR_draco_mesh_compression", "EXT_mesh_gpu_instancing", "EXT_texture_webp", "EXT_texture_avif",
    "MSFT_texture_dds",
})


def check_extensions(names, what, path, why=""):
    """A `FormatError` ``{what} {name!r}{why} (supported: ...)`` for the first of `names` that is not
    supported (see `SUPPORTED_EXTENSIONS`)."""
    unsupported = [e for e in names if not (e in SUPPORTED_EXTENSIONS or e.startswith("KHR_materials_"))]
    if unsupported:
        raise FormatError(f"{what} {unsupported[0]!r}{why} (supported: {', '.join(sorted(SUPPORTED_EXTENSIONS))}, "
                          "KHR_materials_*)", path)


@dataclasses.dataclass
class GltfFile:
    """A glTF file as read: its JSON document and the bytes of its buffers.

    Attributes
    ----------
    json : dict
        The document, as parsed.
    buffers : list of bytes
        The data of ``json["buffers"][i]`` (at least ``byteLength`` bytes).
    path : str
        The file read (named in error messages).
    layout : {'glb', 'embedded', 'external'}
        Where the buffers were: a GLB ``BIN`` chunk, data URIs only, or (some
        of them) files beside a ``.gltf``.
    """

    json: dict
    buffers: list
    path: str
    layout: str


@dataclasses.dataclass
class Sampler:
    """One animation sampler, decoded.

    Attributes
    ----------
    times : ndarray, shape (K,)
        Key times (float64), strictly increasing.
    values : ndarray, shape (K, n) or (3 K, n)
        One row per key (CUBICSPLINE: in-tangent, value, out-tangent rows),
        float64; morph weights have one column per target.  Rotation keys of
        STEP and LINEAR samplers are normalised.
    interpolation : str
        'STEP', 'LINEAR' or 'CUBICSPLINE'.
    path : str or None
        The target path of the channels using it ('rotation', 'translation',
        'scale', 'weights'), None if no channel uses it.
    type : str
        The accessor type of the output ('VEC4', 'VEC3', 'SCALAR', ...).
    """

    times: np.ndarray
    values: np.ndarray
    interpolation: str
    path: str
    type: str


# --------------------------------------------------------------------------- reading

def _glb_chunks(data, path):
    """(JSON bytes, BIN bytes or None) of a GLB file."""
    if len(data) < 20:
        raise FormatError(f"truncated GLB file ({len(data)} bytes, a header needs 20)", path)
    _, version, length = struct.unpack_from("<4sII", data)
    if version != 2:
        raise FormatError(f"expected GLB container version 2, got {version}", path)
    if length > len(data):
        raise FormatError(f"truncated GLB file: the header says {length} bytes, the file has {len(data)}", path)
    chunks, at = [], 12
    while at + 8 <= length:
        size, kind = struct.unpack_from("<II", data, at)
        if at + 8 + size > length:
            raise FormatError(f"truncated GLB chunk at byte {at}: {size} bytes declared, "
                              f"{length - at - 8} left", path)
        chunks.append((kind, data[at + 8:at + 8 + size]))
        at += 8 + size + (-size % 4)
    if not chunks or chunks[0][0] != JSON_CHUNK:
        raise FormatError("the first GLB chunk is not JSON", path)
    bins = [c for kind, c in chunks[1:2] if kind == BIN_CHUNK]
    return chunks[0][1], (bins[0] if bins else None)


def _load_buffer(i, buf, bin_chunk, folder, path):
    uri = buf.get("uri")
    if uri is None:
        if i == 0 and bin_chunk is not None:
            return bin_chunk, "glb"
        raise FormatError(f"buffer {i} has no uri and the file has no GLB BIN chunk to hold it", path)
    if not isinstance(uri, str):
        raise FormatError(f"buffer {i}: expected a string uri, got {type(uri).__name__}", path)
    if uri.startswith("data:"):
        head, _, payload = uri.partition(",")
        if not head.endswith(";base64"):
            raise FormatError(f"buffer {i}: expected a base64 data URI, got {head[:40]!r}", path)
        try:
            return base64.b64decode(payload, validate=True), "embedded"
        except (binascii.Error, ValueError) as exc:
            raise FormatError(f"buffer {i}: bad base64 data URI ({exc})", path) from None
    if len(urllib.parse.urlsplit(uri).scheme) > 1:   # http:, file:, ... (one letter: a Windows drive)
        raise FormatError(f"buffer {i}: cannot read {uri[:60]!r} (only files beside the glTF file)", path)
    file = os.path.join(folder, urllib.parse.unquote(uri))
    try:
        with open(file, "rb") as f:
            return f.read(), "external"
    except OSError as exc:
        raise FormatError(f"buffer {i}: cannot read {uri[:60]!r} ({exc.strerror})", path) from None


def read_gltf(path):
    """Read a ``.gltf`` or ``.glb`` file and the data of its buffers.

    Checks the container, the JSON, ``asset.version`` 2.x, that every
    extension in ``extensionsRequired`` is supported, that every buffer's
    data is there and that every buffer view lies inside its buffer.

    Returns
    -------
    GltfFile

    Raises
    ------
    FormatError
        Naming the file and what is wrong (one line).
    OSError
        The file cannot be opened.
    """
    path = os.fspath(path)
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] == GLB_MAGIC:
        text, bin_chunk = _glb_chunks(data, path)
    else:
        text, bin_chunk = data, None
    try:
        doc = json.loads(text.decode("utf-8-sig"))   # (a byte-order mark is not allowed, but harmless)
    except (UnicodeDecodeError, ValueError) as exc:
        raise FormatError(f"not a glTF file: bad JSON ({exc})", path) from None
    except RecursionError:
        raise FormatError(f"JSON nested more than {MAX_DEPTH} levels deep", path) from None
    if _depth(doc) > MAX_DEPTH:   # copying and writing the document back recurse once per level
        raise FormatError(f"JSON nested more than {MAX_DEPTH} levels deep", path)
    if not isinstance(doc, dict):
        raise FormatError(f"not a glTF file: expected a JSON object, got {type(doc).__name__}", path)
    version = (doc.get("asset") or {}).get("version") if isinstance(doc.get("asset"), dict) else None
    if not (isinstance(version, str) and version.startswith("2.")):
        raise FormatError(f"expected glTF asset.version 2.x, got {version!r}", path)
    _check_shapes(doc, path)
    check_extensions(doc.get("extensionsRequired", []), "unsupported required extension", path)
    folder = os.path.dirname(os.path.abspath(path))
    buffers, layouts = [], set()
    for i, buf in enumerate(doc.get("buffers", [])):
        blob, layout = _load_buffer(i, buf, bin_chunk, folder, path)
        length = buf.get("byteLength")
        if not (isinstance(length, int) and 0 <= length <= len(blob)):
            raise FormatError(f"buffer {i}: byteLength {length!r}, but {len(blob)} bytes of data", path)
        buffers.append(blob)
        layouts.add(layout)
    for j, view in enumerate(doc.get("bufferViews", [])):
        b, start, size = view.get("buffer"), view.get("byteOffset", 0), view.get("byteLength")
        if not (isinstance(b, int) and 0 <= b < len(buffers)):
            raise FormatError(f"bufferView {j}: buffer {b!r} does not exist (the file has {len(buffers)})", path)
        if not (isinstance(start, int) and isinstance(size, int) and start >= 0 and size >= 0
                and start + size <= doc["buffers"][b]["byteLength"]):
            raise FormatError(f"bufferView {j}: bytes {start!r} + {size!r} are outside buffer {b} "
                              f"({doc['buffers'][b]['byteLength']} bytes)", path)
    layout = "glb" if bin_chunk is not None else "external" if "external" in layouts else "embedded"
    return GltfFile(doc, buffers, path, layout)


def _depth(doc):
    """How deeply `doc` (parsed JSON) nests arrays and objects (counted without recursion, up to
    one past `MAX_DEPTH`)."""
    deepest, stack = 0, [(doc, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, (dict, list)):
            deepest = max(deepest, depth)
            if deepest > MAX_DEPTH:
                break
            stack.extend((x, depth + 1) for x in (item.values() if isinstance(item, dict) else item))
    return deepest


def _index(x):
    """An integer (an index, a count, an enum) as JSON gives it: int, not bool."""
    return type(x) is int


def _objects(container, key, where, path):
    """``container[key]``, an array of JSON objects (empty when absent); FormatError otherwise."""
    items = container.get(key, [])
    if not (isinstance(items, list) and all(isinstance(x, dict) for x in items)):
        raise FormatError(f"{where}{key}: expected an array of objects, got {json.dumps(items)[:60]}", path)
    return items


def _object(container, key, where, path):
    """``container[key]``, a JSON object (empty when absent); FormatError otherwise."""
    item = container.get(key, {})
    if not isinstance(item, dict):
        raise FormatError(f"{where}{key}: expected an object, got {json.dumps(item)[:60]}", path)
    return item


def _check_shapes(doc, path):
    """The JSON shapes of everything read or renumbered: arrays of objects, objects where objects go."""
    for key in ("accessors", "bufferViews", "buffers", "animations", "meshes", "skins", "nodes", "images"):
        _objects(doc, key, "", path)
    for key in ("extensionsUsed", "extensionsRequired"):
        names = doc.get(key, [])
        if not (isinstance(names, list) and all(isinstance(e, str) for e in names)):
            raise FormatError(f"{key}: expected an array of strings, got {json.dumps(names)[:60]}", path)
    for a, anim in enumerate(doc.get("animations", [])):
        _objects(anim, "samplers", f"animations[{a}].", path)
        for c, channel in enumerate(_objects(anim, "channels", f"animations[{a}].", path)):
            _object(channel, "target", f"animations[{a}].channels[{c}].", path)
    for a, acc in enumerate(doc.get("accessors", [])):
        sparse = _object(acc, "sparse", f"accessors[{a}].", path)
        for part in ("indices", "values"):
            _object(sparse, part, f"accessors[{a}].sparse.", path)
    for m, mesh in enumerate(doc.get("meshes", [])):
        for p, prim in enumerate(_objects(mesh, "primitives", f"meshes[{m}].", path)):
            where = f"meshes[{m}].primitives[{p}]."
            _object(prim, "attributes", where, path)
            _objects(prim, "targets", where, path)
            _object(_object(prim, "extensions", where, path), "KHR_draco_mesh_compression", where + "extensions.",
                    path)
    for n, node in enumerate(doc.get("nodes", [])):
        where = f"nodes[{n}].extensions."
        instancing = _object(_object(node, "extensions", f"nodes[{n}].", path), "EXT_mesh_gpu_instancing",
                             where, path)
        _object(instancing, "attributes", where + "EXT_mesh_gpu_instancing.", path)


def _elements(gf, view_index, offset, count, dtype, n, what):
    """(count, n) view of elements of `dtype` in buffer view `view_index` (byteStride honoured)."""
    views = gf.json.get("bufferViews", [])
    if not (isinstance(view_index, int) and 0 <= view_index < len(views)):
        raise FormatError(f"{what}: bufferView {view_index!r} does not exist (the file has {len(views)})", gf.path)
    view = views[view_index]
    size = dtype.itemsize * n
    step = view.get("byteStride", size)
    if not (_index(step) and step == size or (_index(step) and 4 <= step <= 252 and step % 4 == 0 and step >= size)):
        raise FormatError(f"{what}: bufferView {view_index} has byteStride {step!r}; expected an integer multiple of "
                          f"4 from 4 to 252, at least the {size} bytes of an element", gf.path)
    if not (isinstance(offset, int) and offset >= 0):
        raise FormatError(f"{what}: expected a byteOffset >= 0, got {offset!r}", gf.path)
    need = offset + step * (count - 1) + size
    if need > view["byteLength"]:
        raise FormatError(f"{what}: {count} elements of {size} bytes from byte {offset} need {need} bytes, "
                          f"bufferView {view_index} has {view['byteLength']}", gf.path)
    return np.ndarray((count, n), dtype=dtype, buffer=gf.buffers[view["buffer"]],
                      offset=view.get("byteOffset", 0) + offset, strides=(step, dtype.itemsize))


def read_accessor(gf, index, what="accessor"):
    """Decode accessor `index` of `gf` to float64 of shape (count, components).

    Float and integer components; normalized integers are decoded as the spec
    says (``max(c / 127, -1)`` for bytes, ``c / 255`` for unsigned bytes,
    likewise for shorts); sparse accessors are applied on top of their base
    (zeros without a bufferView).  Only SCALAR and VECn types (all animation
    data is).  `what` names the user of the accessor in messages.
    """
    accessors = gf.json.get("accessors", [])
    if not (isinstance(index, int) and not isinstance(index, bool) and 0 <= index < len(accessors)):
        raise FormatError(f"{what}: accessor {index!r} does not exist (the file has {len(accessors)})", gf.path)
    acc = accessors[index]
    what = f"{what}: accessor {index}"
    ctype, kind, count = acc.get("componentType"), acc.get("type"), acc.get("count")
    if not (_index(ctype) and ctype in _COMPONENTS):
        raise FormatError(f"{what}: unknown componentType {ctype!r}", gf.path)
    if not (isinstance(kind, str) and kind in SIZES):
        raise FormatError(f"{what}: expected type SCALAR, VEC2, VEC3 or VEC4, got {kind!r}", gf.path)
    if not (_index(count) and count >= 1):
        raise FormatError(f"{what}: expected count >= 1, got {count!r}", gf.path)
    dtype, n = np.dtype(_COMPONENTS[ctype]), SIZES[kind]
    if "bufferView" in acc:
        out = _elements(gf, acc["bufferView"], acc.get("byteOffset", 0), count, dtype, n, what).astype(np.float64)
    else:
        out = np.zeros((count, n))
    sparse = acc.get("sparse")
    if sparse:
        m, ind, val = sparse.get("count"), sparse.get("indices") or {}, sparse.get("values") or {}
        if not (_index(m) and 1 <= m <= count and _index(ind.get("componentType"))
                and ind["componentType"] in _INDEX_COMPONENTS):
            raise FormatError(f"{what}: bad sparse count {m!r} or index componentType "
                              f"{ind.get('componentType')!r}", gf.path)
        rows = _elements(gf, ind.get("bufferView"), ind.get("byteOffset", 0), m,
                         np.dtype(_COMPONENTS[ind["componentType"]]), 1, what + " sparse indices")[:, 0]
        if rows.max() >= count:
            raise FormatError(f"{what}: sparse index {int(rows.max())} is outside the {count} elements", gf.path)
        out[rows.astype(np.intp)] = _elements(gf, val.get("bufferView"), val.get("byteOffset", 0), m, dtype, n,
                                              what + " sparse values")
    if acc.get("normalized"):
        if ctype not in _NORMALISED:
            raise FormatError(f"{what}: normalized is only for integer components, got componentType {ctype}",
                              gf.path)
        out /= _NORMALISED[ctype]
        np.maximum(out, -1.0, out=out)
    return out


def read_animations(gf):
    """Every animation's samplers, decoded: a list (one per animation) of lists of `Sampler`.

    Checks the channels (sampler index, target path), that input times are
    finite and strictly increasing, that the output holds a whole number of
    values per key of the type its path needs, and that no rotation key is
    zero.  Rotation keys of STEP and LINEAR samplers are normalised (keys
    stored as normalized integers are unit only to their precision).
    """
    doc, path = gf.json, gf.path
    result = []
    for a, anim in enumerate(doc.get("animations", [])):
        where = f"animation {a}" + (f" ({anim['name']!r})" if isinstance(anim.get("name"), str) else "")
        samplers = anim.get("samplers", [])
        paths = [set() for _ in samplers]
        for c, channel in enumerate(anim.get("channels", [])):
            s, target = channel.get("sampler"), channel.get("target") or {}
            if not (isinstance(s, int) and 0 <= s < len(samplers)):
                raise FormatError(f"{where} channel {c}: sampler {s!r} does not exist "
                                  f"(the animation has {len(samplers)})", path)
            node, nodes = target.get("node"), doc.get("nodes", [])
            if node is not None and not (_index(node) and 0 <= node < len(nodes)):
                raise FormatError(f"{where} channel {c}: target node {node!r} does not exist "
                                  f"(the file has {len(nodes)} nodes)", path)
            if not (isinstance(target.get("path"), str) and target["path"] in _PATH_TYPES):
                raise FormatError(f"{where} channel {c}: unsupported target path {target.get('path')!r} "
                                  f"(expected {', '.join(_PATH_TYPES)})", path)
            paths[s].add(target["path"])
        decoded = []
        for s, sampler in enumerate(samplers):
            what = f"{where} sampler {s}"
            if len(paths[s]) > 1 and "rotation" in paths[s]:
                raise FormatError(f"{what}: drives both rotation and {sorted(paths[s] - {'rotation'})[0]}", path)
            target = min(paths[s]) if paths[s] else None
            interpolation = sampler.get("interpolation", "LINEAR")
            if interpolation not in INTERPOLATIONS:
                raise FormatError(f"{what}: expected interpolation in {INTERPOLATIONS}, got {interpolation!r}", path)
            times = read_accessor(gf, sampler.get("input"), what + " input")
            if times.shape[1] != 1:
                raise FormatError(f"{what}: expected SCALAR input times, got {times.shape[1]} components", path)
            times = times[:, 0]
            bad = ~np.isfinite(times)
            bad[1:] |= ~(np.diff(times) > 0)
            if bad.any():
                k = int(np.argmax(bad))
                raise FormatError(f"{what}: input times must be finite and strictly increasing, "
                                  f"key {k} is {float(times[k])!r}", path)
            values = read_accessor(gf, sampler.get("output"), what + " output")
            out_type = doc["accessors"][sampler["output"]]["type"]
            ctype = doc["accessors"][sampler["output"]]["componentType"]
            normalized = doc["accessors"][sampler["output"]].get("normalized") is True
            if target in ("rotation", "weights") and not (ctype == FLOAT or (ctype in _NORMALISED and normalized)):
                raise FormatError(f"{what}: {target} output of componentType {_NAMES[ctype]}"
                                  f"{'' if normalized or ctype not in _NORMALISED else ' (not normalized)'}; "
                                  "expected FLOAT or a normalized BYTE, UNSIGNED_BYTE, SHORT or UNSIGNED_SHORT", path)
            per_key = 3 * len(times) if interpolation == "CUBICSPLINE" else len(times)
            if len(values) % per_key or (target is not None and out_type != _PATH_TYPES[target]) \
                    or (target in ("rotation", "translation", "scale") and len(values) != per_key):
                raise FormatError(f"{what}: output of {len(values)} {out_type} does not fit {len(times)} keys "
                                  f"of {interpolation} {target or 'values'}", path)
            values = values.reshape(per_key, -1)
            if not np.isfinite(values).all():
                raise FormatError(f"{what}: non-finite output value", path)
            if target == "rotation":
                cubic = interpolation == "CUBICSPLINE"
                rows = values.reshape(len(times), -1, 4)[:, 1 if cubic else 0]
                norm = np.linalg.norm(rows, axis=-1)
                if not (norm > 0).all():
                    raise FormatError(f"{what}: rotation key {int(np.argmin(norm))} is zero", path)
                if not cubic:   # (CUBICSPLINE: the spec normalises the curve, not the keys)
                    rows /= norm[:, None]
            decoded.append(Sampler(times, values, interpolation, target, out_type))
        result.append(decoded)
    return result
