"""Plots of spiralbayes results; every function returns a Matplotlib Figure (Agg-safe)."""
