"""Incremental Gaussian mixtures, GMR and the forward models built on them (seed A §3.1)."""
