"""Identification of a first-order (or ARX) model from sampled input/output data."""
