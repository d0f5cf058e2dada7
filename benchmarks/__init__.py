"""Benchmarks for quatarray: asv suites and a side-by-side comparison.

One module per area (``algebra``, ``rotate``, ``conversions``, ``pairwise``,
``tracks``, ``resample``); each class takes a ``lib`` parameter so that asv
shows quatarray, scipy, numpy-quaternion and quaternionic side by side on the
same data.  ``python -m benchmarks.compare`` times the same benchmarks
interleaved in one process and checks the speed targets (`compare.targets`);
``python -m benchmarks.ufuncs`` prints the per-element cost of the ufuncs
the kernels choose between (see benchmarks/README.md).

Nothing here is imported by quatarray itself; the peers are optional.
"""

import importlib.util as _util
import os as _os
import sys as _sys

if _util.find_spec("quatarray") is None:  # a checkout that is not installed: benchmark it in place
    _sys.path.insert(0, _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))

