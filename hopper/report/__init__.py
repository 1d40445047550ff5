"""Figures and reports of runs, recordings and sweeps (`hopper-sim report`): matplotlib, Agg backend.

One concern per module: `style` (the shared look), `runs` (a run's time series and hop table,
from a run's JSON), `rrd` (the same, read from a rerun recording), `run_figures` (the paper's
figures of a run, wheel on vs off), `sweep` (a sweep's Parquet datasets and their figures),
`page` (one self-contained HTML page), `folder` (a report's folder, replaced whole). Every
figure function returns a matplotlib Figure.
"""
