"""Measuring: the clocks and what they are read against, used inside a worker process.
``timing`` (first call, steady state, the throughput regime, the host profile: typed ``Regime``
parts), ``noise`` (was the host busy while a cell was timed: the record's verdict), ``nvml``
(device memory and clocks), ``environment`` (the machine, the packages, the run stamp) and
``phases`` (where a cell's wall time went). Imports only results."""
