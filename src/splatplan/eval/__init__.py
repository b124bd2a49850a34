"""Evaluation stage: one module per study of the paper (pr, throughput, conservatism, linearization)."""
