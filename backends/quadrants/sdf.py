"""Procedural SDF image in Quadrants: the Taichi kernel (backends/taichi/sdf.py) built with
``quadrants``.

Quadrants is Taichi's maintained fork with the same API under another module name (``qd`` for
``ti``), so one definition serves both: nothing differs but the module. Storage: a field, as there
(measured on Taichi 1.7: a field no slower than an ndarray, identical images). Literals are
Quadrants default_fp, i.e. the cell's precision (set by qd.init).
"""
import quadrants as qd

from ..taichi.sdf import build

_sdf, Kernel = build(qd)
