"""Exact discrete simulation of the paper's plant (eq. 4)."""
