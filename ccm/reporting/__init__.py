"""Claims, the paper pipeline and the report over a directory of runs."""
