"""ccm: changing-contact robot manipulation — reproductions of seed A (Sidhik et al.) and seed B
(Haninger et al.) in simulation, with their baselines, tasks and an experiment runner."""

__version__ = "0.1.0"
