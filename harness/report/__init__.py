"""What a run shows: tidy results, summaries, the paper's tables and figures, the run record,
nightly tracking. Imports methods/metrics registries, views, io and core; never harness.run."""
