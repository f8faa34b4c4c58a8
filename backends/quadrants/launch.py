"""Trivial launch in Quadrants: the Taichi kernel (backends/taichi/launch.py) built with
``quadrants``.

Quadrants is Taichi's maintained fork with the same API under another module name (``qd`` for
``ti``), so one definition serves both: nothing differs but the module.
"""
import quadrants as qd

from ..taichi.launch import build

_plus_one, Kernel = build(qd)
