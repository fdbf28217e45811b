"""The public Python API, exported at the top of the package (``harness.prune`` ...; see the README).

One module per subject: :mod:`.scenes` (load, save, info, score, prune, methods), :mod:`.images`
(render, compare), :mod:`.study` (evaluate). The commands of :mod:`harness.commands` are these
functions plus their flags and printing.
"""

from harness.api.images import compare, render
from harness.api.scenes import Pruned, info, load, methods, prune, save, score
from harness.api.study import evaluate

__all__ = ["Pruned", "compare", "evaluate", "info", "load", "methods", "prune", "render", "save", "score"]
