"""Per-trial and per-condition metrics (the summary.json numbers; names carry units)."""
