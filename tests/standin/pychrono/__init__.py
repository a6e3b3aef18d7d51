"""``import pychrono`` in a process without PyChrono: the stand-in of tests/pychrono_standin.py.

With ``tests`` and ``tests/standin`` on PYTHONPATH (as tests/test_docs.py runs the
documentation's PyChrono examples), ``import pychrono`` and ``import pychrono.vehicle``
give the stand-in's modules, e.g. ``PYTHONPATH=tests:tests/standin python site_soil.py``.
"""

import sys

from pychrono_standin import modules

_chrono, _vehicle = modules()
globals().update({k: v for k, v in vars(_chrono).items() if not k.startswith("__")})
sys.modules[f"{__name__}.vehicle"] = _vehicle
