"""``make bench``: speed and memory benchmarks (tables + JSON), never unit-test assertions."""
