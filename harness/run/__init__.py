"""A run: config → plan → cached stages (score, prune, render, metrics) on a pool → tidy results.
May import everything below it (report, methods, renderers, metrics, views, io, core); nothing
below imports it."""
