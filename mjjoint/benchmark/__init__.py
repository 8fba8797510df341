"""Concealed-effect benchmark: closed-loop lab recordings from a richer truth, scored blind."""
