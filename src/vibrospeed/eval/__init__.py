"""Evaluation: metrics against ground truth, plots. Library code used by the CLI and benchmarks."""
