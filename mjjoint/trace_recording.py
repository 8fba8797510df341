"""The traces of one run as a recording: columns t, u1, q1, theta1, tau1, u2, ... (SI)."""
from __future__ import annotations

from pathlib import Path

from .recordings import MultiRecording, Recording, write_recording
from .sim import Trace


def recording(traces: list[Trace] | Trace) -> MultiRecording:
    """Traces as a recording: columns t, u1, q1, theta1, tau1, u2, ..."""
    traces = [traces] if isinstance(traces, Trace) else list(traces)
    return MultiRecording(tuple(Recording(t=tr.t, u=tr.u, q=tr.q, theta=tr.theta, tau=tr.tau,
                                          gear_ratio=tr.gear_ratio) for tr in traces))


def write_traces_csv(path: str | Path, traces: list[Trace]) -> Path:
    """Per-joint CSV (``t,u1,q1,theta1,tau1,u2,...``) of the traces of one run."""
    write_recording(path, recording(traces))
    return Path(path)
