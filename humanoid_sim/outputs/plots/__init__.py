"""outputs.plots."""
