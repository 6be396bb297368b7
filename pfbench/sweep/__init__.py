"""Monte Carlo sweeps on local processes or Dask, with a resumable store (``pfbench sweep``)."""
from .core import make_spec, run_chunk, run_multipdf, run_particle_family
from .runner import SweepReport, run_sweep
from .store import Store, load_frame
from .summary import plot_summary, summarize_frame, throughput

__all__ = ["make_spec", "run_chunk", "run_multipdf", "run_particle_family", "run_sweep", "SweepReport", "Store",
           "load_frame", "summarize_frame", "plot_summary", "throughput"]
