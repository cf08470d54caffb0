"""An example ccm plugin package: one controller, its config and its contract test."""
