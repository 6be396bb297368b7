"""Particle filters. :func:`run_filter` runs bootstrap / SIR / SIS / MultiPDF / ASIR on either
backend; specialised filters (marginalized PF, optimal-proposal SMC) live in their own modules."""
from .api import METHODS, FilterResult, run_filter

__all__ = ["run_filter", "FilterResult", "METHODS"]
