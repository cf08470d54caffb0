"""ccm: changing-contact robot manipulation — reproductions of seed A (Sidhik et al.) and seed B
(Haninger et al.) in simulation, with their baselines, tasks and an experiment runner."""

__version__ = "0.1.0"

from ccm.reporting.load import Run, load_run  # noqa: E402  (after the version: a light, files-only import)

__all__ = ["Run", "load_run", "__version__"]
