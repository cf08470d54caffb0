"""Tasks: scenes and target motion patterns P, built from YAML."""
