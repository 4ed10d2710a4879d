"""Rigs: one interface for the digital twin and every hardware driver."""
