"""Benchmarks for `harness bench` (one module each) and their shared helpers."""
