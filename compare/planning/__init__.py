"""Planning: what is decided before a cell runs. ``outdir`` (is --out ours to write: refusals,
the claim), ``preflight`` (memory and disk a plan needs; every byte constant), ``calibrate``
(a big cell timed in miniature predicts its time and memory) and ``publish_plan`` (the parts a
``publish`` runs, with their exact commands)."""
