"""Run configs for ``harness run CONFIG.yaml``: read, checked, expanded and shown.

* :mod:`~harness.run.config.run_config`: :class:`RunConfig`, :func:`load_config` / :func:`parse_config`
  (validation and sweep expansion);
* :mod:`~harness.run.config.sections`: the sections as dataclasses of typed ``config_param(...)`` fields,
  read by :mod:`~harness.run.config.schema` with the checks of :mod:`~harness.run.config.checks`;
* :mod:`~harness.run.config.views`: the ``protocols:`` list and a scene's ``capture:``;
* :mod:`~harness.run.config.executor`: the ``executor:`` section;
* :mod:`~harness.run.config.files`: ``extends:`` and where every value came from;
* :mod:`~harness.run.config.show`: ``harness config show``.
"""

from harness.run.config.run_config import (
    SECTIONS,
    MethodVariant,
    RunConfig,
    SceneSpec,
    load_config,
    merge_ratios,
    parse_config,
)

__all__ = ["SECTIONS", "MethodVariant", "RunConfig", "SceneSpec", "load_config", "merge_ratios", "parse_config"]
