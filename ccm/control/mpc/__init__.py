"""Seed B's GP model-predictive impedance control: model, cost terms, problem, codegen."""
