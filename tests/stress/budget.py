"""Case budgets of the stress suite: bounded in CI, large with ``HARNESS_STRESS=full``.

The Hypothesis settings are registered as two profiles (``harness-stress-ci``, ``harness-stress-full``)
and applied per test through :data:`HYPOTHESIS` (never loaded globally, so other test files keep
their own settings). No deadline: the shared two-core machine makes per-example timing meaningless.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

FULL = os.environ.get("HARNESS_STRESS", "").strip().lower() == "full"


def mode() -> str:
    return "full" if FULL else "ci"


def n(ci: int, full: int) -> int:
    """The case count for this mode."""
    return full if FULL else ci


settings.register_profile("harness-stress-ci", max_examples=40, deadline=None, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.register_profile("harness-stress-full", max_examples=1500, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
HYPOTHESIS = settings.get_profile(f"harness-stress-{mode()}")


def examples(ci: int, full: int) -> settings:
    """Profile settings with an explicit example count (slow families need fewer)."""
    return settings(HYPOTHESIS, max_examples=n(ci, full))
