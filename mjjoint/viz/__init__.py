"""Visualisation of simulated and recorded traces (Rerun)."""
from .rerun_log import log_traces

__all__ = ["log_traces"]
