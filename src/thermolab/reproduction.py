"""Reproduction of the paper's Table I."""
