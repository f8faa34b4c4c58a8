"""Bouncing particles in Quadrants: the Taichi kernel (backends/taichi/particles.py) built with
``quadrants``: one parallel-for iteration per particle, all steps in registers.

Quadrants is Taichi's maintained fork with the same API under another module name (``qd`` for
``ti``), so one definition serves both: nothing differs but the module. Storage: fields, as there
(the kernel is compute-bound; on Taichi 1.7 fields had the lower launch overhead).
"""
import quadrants as qd

from ..taichi.particles import build

_rollout, Kernel = build(qd)
