"""Contract checks a controller or simulator can run against ccm's protocols (issue #40:
the step objects; issue #41 extends the kit)."""
