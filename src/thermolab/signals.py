"""Excitation signals and their text syntax."""
