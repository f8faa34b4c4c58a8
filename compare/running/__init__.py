"""Running: cells in worker processes. ``engine.run_cells`` skips what cannot run, runs the rest
(``cells``: one fresh interpreter per cell; ``worker``: inside it, inputs -> kernel -> timing ->
check -> record), types each record once and hands it to the suite; it runs the plan once (the
repeats across processes are the driver's, ``compare.suites.driver.more_processes``, with the
seeded rounds and statistics of ``repeats``). ``overlap`` and ``gate`` set workers up side by side and time
them one at a time; ``lifeline`` makes children die with the driver; ``scaleout`` runs cells on
Dask workers, one per GPU; ``lock`` keeps one driver per output folder; ``hardware`` measures the
yardstick (copy bandwidth, launch latency) in its own process."""
