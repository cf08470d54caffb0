"""Learners (IGMM, GMR, mode clustering, contact Kalman filter, GP models): numpy/sklearn-style
objects with no simulator or controller imports."""
