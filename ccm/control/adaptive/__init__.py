"""Seed A's controllers: AVIC (Eq. 4), mode-aware AVIC and the anticipating framework."""
