"""Sub-commands of `harness`, one module each (discovered by :mod:`harness.cli`)."""
