"""Judging a calibration: Table I and the compensation test (prediction), in-situ split
evaluation, the real-data and transfer benches, and the HTML report."""
