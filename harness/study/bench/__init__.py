"""The study's benchmarks, ``harness bench reading|virtualrig|tradeoff`` (entry-point group
``harness.benchmarks``: :func:`harness.commands.bench.benchmarks`)."""
