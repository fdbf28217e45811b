"""The paper study: the lab beside the product.

What the study of BetaDescPrune's paper needs and a user of the harness does not: the ``claims``
table and its verdict rules (:mod:`~harness.study.claims`, :mod:`~harness.study.verdicts`), the
pre-registered selection engines of the default reading and of the virtual rig
(:mod:`~harness.study.reading_search`, :mod:`~harness.study.paired`, driven by
:mod:`~harness.study.selection`), which way each reading points (:mod:`~harness.study.directions`),
and the speed/accuracy knobs' measurements (:mod:`~harness.study.tradeoff_knobs`); their configs
live in ``ctc_configs/study/``.

It plugs into the harness the way a third-party package does, through entry points of this
project's ``pyproject.toml``: ``harness.tables`` names :mod:`harness.study.tables` (the ``claims``
table) and ``harness.benchmarks`` the modules of :mod:`harness.study.bench` (``harness bench
reading``, ``virtualrig``, ``tradeoff``). The study may import anything of the product; nothing of
the product imports the study (``tests/test_layers.py``).
"""
