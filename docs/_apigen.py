"""Write the API reference's index from quatarray's public names.

Every name in ``quatarray.__all__`` and in the ``__all__`` of the public
submodules gets a page (autosummary), in one of the groups below.  A name
this file does not know yet is placed by the module that defines it, so a
new public function appears in the reference without editing the docs.
"""

import contextlib
import importlib
import importlib.util
import inspect
import io
import os

import quatarray

#: (key, title, introduction), in page order.
GROUPS = [
    ("arrays", "Arrays and algebra",
     "`QuatArray` is the ndarray subclass; its operators and NumPy functions are described in "
     ":doc:`/guide/numpy`.  The thread controls decide how many threads long batches use."),
    ("rotations", "Rotations (scipy-compatible)",
     "Drop-in replacements for :mod:`scipy.spatial.transform` classes: see "
     ":doc:`/guide/rotations` for what differs."),
    ("interpolation", "Interpolation",
     "Pairwise interpolation, curve control points, keyframe tracks, scipy's `Slerp` and "
     "`RotationSpline`, and screw interpolation of rigid motions. See :doc:`/guide/interpolation`."),
    ("timeseries", "Time series",
     "Fewer keys within a stated angular error, angular velocity to orientations and back, minimal "
     "rotation, swing-twist, the geodesic mean, smoothing and gap filling; see :doc:`/guide/timeseries`."),
    ("files", "Files and command line",
     "Readers, writers and resampling of keyframe files; see :doc:`/guide/files`."),
    ("dask", "Scaling out (Dask)",
     "The in-memory kernels on Dask arrays, chunk by chunk, and keyframe tracks evaluated at "
     "chunked times; see :doc:`/guide/dask`."),
    ("testing", "Testing helpers",
     "Assertions that compare quaternion arrays (``numpy.testing`` applies componentwise ufuncs "
     "that `QuatArray` refuses)."),
]

#: Top-level names placed by hand; anything else is placed by `_group_of_module`.
NAMES = {
    "QuatArray": "arrays", "set_num_threads": "arrays", "get_num_threads": "arrays",
    "num_threads": "arrays",
    "Rotation": "rotations", "RigidTransform": "rotations",
    "Slerp": "interpolation", "RotationSpline": "interpolation", "Track": "interpolation",
}

#: Public submodules and their group, documented through their ``__all__``.
SUBMODULES = {"formats": "files", "cli": "files", "dask": "dask", "testing": "testing"}


def _group_of_module(module):
    parts = module.split(".")
    for key, group in (("dask", "dask"), ("testing", "testing"), ("formats", "files"), ("cli", "files"),
                       ("_rotation", "rotations"), ("_rigid_transform", "rotations")):
        if key in parts:
            return group
    if "timeseries" in parts or "_reduce" in parts or "_timeseries" in parts:
        return "timeseries"
    if any(k in module for k in ("interp", "spline", "rigid", "track", "dualquat")):
        return "interpolation"
    return "arrays"


def public_objects():
    """[(group, qualified name, object)] for every public name, each object once."""
    out, seen = [], {}
    for name in quatarray.__all__:
        obj = getattr(quatarray, name)
        if inspect.ismodule(obj):
            continue
        group = NAMES.get(name) or _group_of_module(getattr(obj, "__module__", "") or "")
        out.append((group, f"quatarray.{name}", obj))
        seen.setdefault(id(obj), name)
    for sub, group in SUBMODULES.items():
        if importlib.util.find_spec(f"quatarray.{sub}") is None:
            continue
        mod = importlib.import_module(f"quatarray.{sub}")
        for name in getattr(mod, "__all__", []):
            obj = getattr(mod, name)
            if id(obj) in seen or inspect.ismodule(obj) or (sub == "cli" and name == "main"):
                continue      # documented under its top-level name; `main` is the command itself
            seen[id(obj)] = name
            out.append((group, f"quatarray.{sub}.{name}", obj))
    return out


def own_members():
    """{qualified class name: {"methods": [...], "attributes": [...]}}: public members that
    quatarray's own classes define (ndarray's inherited members are left out)."""
    result = {}
    for _, qualname, obj in public_objects():
        if not inspect.isclass(obj) or qualname.rsplit(".", 1)[1] != obj.__name__:
            continue                      # an alias shows as "alias of ..." without members
        methods, attributes, seen = [], [], set()
        for klass in obj.__mro__:
            if not (klass.__module__ or "").startswith("quatarray"):
                continue
            for name, value in vars(klass).items():
                if name in seen or (name.startswith("_") and name != "__call__"):
                    continue
                seen.add(name)
                doc = getattr(value.fget if isinstance(value, property) else
                              getattr(value, "__func__", value), "__doc__", None)
                if not doc and name != "__call__":
                    continue              # an override kept silent (reshape, ravel, ...) is ndarray's API
                if isinstance(value, property) or not callable(getattr(value, "__func__", value)):
                    if name.isupper():    # a constant (block size, ...) is no API
                        continue
                    attributes.append(name)
                else:
                    methods.append(name)
        result[qualname] = {"methods": methods, "attributes": attributes}
    return result


def _cli_help():
    """``quatarray --help`` and each sub-command's help, as the command prints them."""
    from quatarray import cli
    texts = []
    for argv in (["--help"], ["resample", "--help"], ["reduce", "--help"], ["demo", "--help"]):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf), contextlib.suppress(SystemExit):
            cli.main(argv)
        texts.append((" ".join(["quatarray", *argv]), buf.getvalue()))
    return texts


def write_api_pages(docs_dir):
    """Write ``api/index.rst``, one page per group and ``api/cli.rst`` (build products,
    git-ignored); return the group pages, for ``autosummary_generate``."""
    api = os.path.join(docs_dir, "api")
    os.makedirs(api, exist_ok=True)
    objects = public_objects()
    _remove_stale_pages(os.path.join(api, "generated"), [q for _, q, _ in objects])
    pages = []
    index = ["API reference", "=============", "",
             "One page per public class and function, generated from the docstrings, by topic:",
             "", ".. toctree::", "   :maxdepth: 1", ""]
    for key, title, intro in GROUPS:
        names = [q for g, q, _ in objects if g == key]
        if not names and key != "files":
            with contextlib.suppress(FileNotFoundError):   # a group left over from an older API
                os.remove(os.path.join(api, f"{key}.rst"))
            continue
        index.append(f"   {key}")
        page = [title, "=" * len(title), "", intro, ""]
        if key == "files":
            page += [".. toctree::", "   :hidden:", "", "   cli", "",
                     ":doc:`cli`: the ``quatarray`` command (``resample``, ``reduce``, ``demo``).", ""]
        if names:
            page += [".. autosummary::", "   :toctree: generated", "   :nosignatures:", ""]
            page += [f"   ~{q}" for q in names] + [""]
        _write(os.path.join(api, f"{key}.rst"), "\n".join(page))
        pages.append(f"api/{key}.rst")
    _write(os.path.join(api, "index.rst"), "\n".join(index + [""]))

    cli = ["Command line", "============", "",
           "The ``quatarray`` command (also ``python -m quatarray``). Its help, as printed by the "
           "installed version:", ""]
    for command, text in _cli_help():
        cli += [f"``{command}``", "", ".. code-block:: text", ""]
        cli += ["   " + line if line else "" for line in text.rstrip().splitlines()] + [""]
    _write(os.path.join(api, "cli.rst"), "\n".join(cli))
    return pages


def _remove_stale_pages(generated, names):
    """Delete autosummary pages of objects that are no longer public (a renamed module's
    functions): Sphinx would warn that they are in no toctree, and ``-W`` makes that an error."""
    if not os.path.isdir(generated):
        return
    for file in os.listdir(generated):
        stem = file[:-len(".rst")] if file.endswith(".rst") else None
        if stem and not any(stem == q or stem.startswith(q + ".") for q in names):
            os.remove(os.path.join(generated, file))


def _write(path, text):
    """Write only on change, so that an unchanged API does not re-read every page."""
    try:
        with open(path, encoding="utf-8") as f:
            if f.read() == text:
                return
    except FileNotFoundError:
        pass
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)
