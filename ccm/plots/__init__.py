"""Figures: one module per family, each a few small functions that save labelled PNGs."""
