"""Running experiments: config checks, the trial loop and runner, run records, learned state."""
