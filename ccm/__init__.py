"""ccm: changing-contact robot manipulation — reproductions of seed A (Sidhik et al.) and seed B
(Haninger et al.) in simulation, with their baselines, tasks and an experiment runner.

Every ``import ccm.<anything>`` runs this file first, so it imports nothing: loading a
controller does not load the report, and the layers (``tests/test_layers.py``) hold for the
root too. A run directory as DataFrames: ``from ccm.reporting.load import load_run``.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
