"""Seed A's contact learners: modes, contact anticipation, collisions, approach speed."""
