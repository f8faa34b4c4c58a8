"""Render: a run's own outputs, written from its records. ``report`` and ``results_csv``
(results.md and results.csv), ``console`` (the end-of-run screen), ``charts``, ``run_plots`` and
``figures`` (the pictures), ``colors`` (one definition of the bands and colours), ``figure_check``
(every saved figure's layout checked and stamped in the PNG). The site (compare/site) builds on it."""
