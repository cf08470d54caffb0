"""Gaussian-process force models (seed B §3.1) and the offline modal GP baseline of H3."""
