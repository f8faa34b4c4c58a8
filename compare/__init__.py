"""Driver: runs scenario x backend x device x precision cells in worker processes and reports."""
