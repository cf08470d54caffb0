"""Controllers: ``(Observation, TargetSample) -> Command`` with loggable internal signals."""
