"""SAXPY in Quadrants: the Taichi kernel (backends/taichi/saxpy.py) built with ``quadrants``.

Quadrants is Taichi's maintained fork with the same API under another module name (``qd`` for
``ti``), so one definition serves both: nothing differs but the module. Storage: fields, as there
(measured on Taichi 1.7, 2-core CPU: fields beat ndarrays by 10-30 % at n = 1e5..1e6).
"""
import quadrants as qd

from ..taichi.saxpy import build

_saxpy, Kernel = build(qd)
