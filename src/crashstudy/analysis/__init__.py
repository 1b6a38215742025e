"""What is computed from stored results: comparison, sensitivity, optimisation, plots."""
