"""Adaptive baselines of seed A §4: AIC, MRAC and BAC."""
