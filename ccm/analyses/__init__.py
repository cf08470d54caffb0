"""Experiments that are not a trial sweep: H3, MPC convexity, GP contact models, model horizon."""
