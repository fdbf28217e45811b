"""Test-suite settings shared by every test.

Hypothesis: the property tests run derandomized by default (the same examples on every run), so a CI
run that gates a nightly build is reproducible and a red run can be rerun to the same failure; set
``HYPOTHESIS_PROFILE=explore`` to search with fresh random examples (and keep any failure it finds as
an ``@example``). Deadlines are off everywhere: the shared 2-core machines time nothing reliably.
"""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("harness-default", derandomize=True, deadline=None)
settings.register_profile("explore", deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "harness-default"))
