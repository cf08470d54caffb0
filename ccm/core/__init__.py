"""Bottom layer: data types, errors and validation, filters, protocols, run-file formats."""
