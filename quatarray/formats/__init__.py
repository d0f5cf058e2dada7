"""Keyframe files: one module per format, and the one registry of formats.

- **CSV** (`read_csv`, `write_csv`) -- a header line, a ``time`` column (any
  case), then four columns per track, ``<track>.w,<track>.x,<track>.y,<track>.z``
  (``x, y, z, w`` with ``scalar_last=True``); comma-, tab- or
  semicolon-separated.
- **NPZ** (`read_npz`, `write_npz`) -- arrays ``times`` ``(K,)`` and ``keys``
  ``(K, *batch, 4)``, scalar-first, and optionally ``names``, one track name
  per flattened batch index.
- **BVH** (`read_bvh`, `write_bvh`, `resample_motion`) -- motion capture.
- **glTF 2.0** (`resample_gltf`, `keyframes_to_gltf`) -- ``.gltf`` and ``.glb``.
- **Zarr** (`read_zarr`, `write_zarr`, `resample_zarr`) -- ``.zarr`` stores, the
  NPZ layout (names in the group attribute ``names``); Zarr → Zarr is
  resampled chunk by chunk with Dask, a store converted to or from CSV or NPZ
  is held in memory.

`FORMATS` maps each extension to its `Format` (reader, writer, resampler);
`resample_file` and the ``quatarray`` command go through it.  Every problem
with a file raises `FormatError` carrying the file name and, where there is
one, the line.  Writers write to a temporary file next to the target and
rename it into place only when it is complete, so a failed write leaves no
partial file.
"""

from .bvh import Joint, Motion, read_bvh, resample_motion, write_bvh
from .csv import read_csv, write_csv
from .gltf import keyframes_to_gltf, resample_gltf
from .keyframes import (Keyframes, example_path, fps_steps, fps_times, keys_at_key_times, read_times,
                        resample_keyframes, snap_to_keys)
from .npz import read_npz, write_npz
from .registry import FORMATS, Format, format_of, resample_file
from .text import FormatError, NonUnitKeyWarning, NotCarriedWarning, TextStyle
from .zarr import read_zarr, resample_zarr, write_zarr

__all__ = [
    "FormatError", "NonUnitKeyWarning", "NotCarriedWarning", "TextStyle", "Keyframes", "read_csv", "write_csv", "read_npz", "write_npz",
    "Joint", "Motion", "read_bvh", "write_bvh", "resample_motion", "resample_gltf", "keyframes_to_gltf",
    "read_zarr", "write_zarr", "resample_zarr", "read_times", "fps_times", "fps_steps", "snap_to_keys",
    "resample_keyframes", "keys_at_key_times", "example_path",
    "Format", "FORMATS", "format_of", "resample_file",
]
